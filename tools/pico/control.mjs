// The virtual Pico's world control: the hands of a test rig (lay the board on a face, turn it,
// knock it, heat it) for `make demo BOARD=pico`, tests and scripts, on the HOST side only.
//
// The firmware on the emulated RP2040 cannot reach it: code on the board sees its peripherals
// and nothing else (a real board cannot move the table it lies on). It is a Unix socket beside
// the board's pid file (build/pico/world.sock for `make board BOARD=pico`), created mode 0600
// (umask while binding, never a chmod that could follow a link), so only the user who started
// the board (and root) can connect: the same people who already own the board's REPL pty. A
// path that exists and is not our own stale socket is left alone and the board starts without
// the channel (it says why). The socket is removed when the board stops.
//
// Protocol: one JSON object per line, one JSON answer per line ({"ok": true, "state": {...}}
// or {"ok": false, "error": "..."}). Fixed verbs with checked numbers, nothing evaluated:
//
//   {"cmd": "state"}                                   the world now: RP2040 and world time,
//                                                      temperature, face, rate
//   {"cmd": "place", "face": "+x"}                     lay it still with +x up
//   {"cmd": "spin", "rate": [0, 0, 20]}                a turntable, deg/s about x, y, z
//   {"cmd": "bump", "after_ms": 0, "for_ms": 400}      a knock (optional "rate": [x, y, z] peak)
//   {"cmd": "heat", "points": [[0, 20], [30, 50]]}     a temperature programme from now
//                                                      (world seconds, degC)
//   {"cmd": "temperature", "at_ms": [100, 200]}        the temperature at those RP2040 times
//                                                      (ms since its power-on, as ticks_ms())
//
// Each request runs between two slices of the RP2040's execution, at its simulated time
// (pico_worker.mjs); tools/board/picoctl.py (WorldControl) is the Python client.

import fs from "node:fs";
import net from "node:net";

const MAX_LINE = 4096;
const IDLE_MS = 120000;
const VERBS = new Set(["state", "place", "spin", "bump", "heat", "temperature"]);

function finite(v, lo, hi, what) {
  if (typeof v !== "number" || !Number.isFinite(v) || v < lo || v > hi) {
    throw new Error(`${what} must be a number in [${lo}, ${hi}], got ${JSON.stringify(v)}`);
  }
  return v;
}

function vector(v, what) {
  if (!Array.isArray(v) || v.length !== 3) throw new Error(`${what} must be [x, y, z] deg/s`);
  return v.map((x) => finite(x, -2000, 2000, what));
}

// A request as the world's adapter (pico_bus.control) takes it: only known fields, checked
export function checkRequest(r) {
  if (r === null || typeof r !== "object" || Array.isArray(r)) throw new Error("a request is a JSON object");
  if (!VERBS.has(r.cmd)) throw new Error(`unknown cmd ${JSON.stringify(r.cmd)}: one of ${[...VERBS].join(", ")}`);
  const out = { cmd: r.cmd };
  if (r.cmd === "place") {
    if (typeof r.face !== "string" || !/^[+-][xyz]$/.test(r.face)) throw new Error('face must be "+x", "-z", ...');
    out.face = r.face;
  } else if (r.cmd === "spin") {
    out.rate = vector(r.rate, "rate");
  } else if (r.cmd === "bump") {
    if (r.rate !== undefined) out.rate = vector(r.rate, "rate");
    out.after_ms = Math.round(finite(r.after_ms ?? 0, 0, 3600000, "after_ms"));
    out.for_ms = Math.round(finite(r.for_ms ?? 1000, 1, 600000, "for_ms"));
  } else if (r.cmd === "heat") {
    if (!Array.isArray(r.points) || r.points.length < 1 || r.points.length > 64) {
      throw new Error("points must be 1..64 [seconds, degC] pairs");
    }
    out.points = r.points.map((p) => {
      if (!Array.isArray(p) || p.length !== 2) throw new Error("points must be [seconds, degC] pairs");
      return [finite(p[0], 0, 1e6, "seconds"), finite(p[1], -60, 150, "degC")];
    });
  } else if (r.cmd === "temperature") {
    if (!Array.isArray(r.at_ms) || r.at_ms.length > 100000) throw new Error("at_ms must be a list of up to 100000 times");
    out.at_ms = r.at_ms.map((t) => finite(t, 0, 1e9, "at_ms"));
  }
  return out;
}

// Listen on sockPath; handle(request) -> Promise of the answer object. Returns {close()} or
// null (with the reason logged) when the path is taken by something else.
export function startControl(sockPath, handle, log = console.error) {
  let st = null;
  try {
    st = fs.lstatSync(sockPath);
  } catch (e) {
    if (e.code !== "ENOENT") throw e;
  }
  if (st) {
    // a socket of ours left by a board that was killed: replace it; anything else: not ours
    if (!st.isSocket() || st.uid !== process.getuid()) {
      log(`world control: ${sockPath} exists and is not this user's socket: no world control`);
      return null;
    }
    fs.unlinkSync(sockPath);
  }
  const server = net.createServer((sock) => {
    sock.setTimeout(IDLE_MS, () => sock.destroy());
    let buf = "";
    let queue = Promise.resolve();
    sock.on("data", (d) => {
      buf += d.toString("utf8");
      if (buf.length > MAX_LINE && !buf.slice(0, MAX_LINE).includes("\n")) {
        sock.end(JSON.stringify({ ok: false, error: `a request is one line of at most ${MAX_LINE} bytes` }) + "\n");
        sock.destroy();
        return;
      }
      let nl;
      while ((nl = buf.indexOf("\n")) >= 0) {
        const line = buf.slice(0, nl).trim();
        buf = buf.slice(nl + 1);
        if (!line) continue;
        queue = queue.then(async () => {
          let answer;
          try {
            answer = await handle(checkRequest(JSON.parse(line)));
          } catch (e) {
            answer = { ok: false, error: String(e.message || e) };
          }
          if (!sock.destroyed) sock.write(JSON.stringify(answer) + "\n");
        });
      }
    });
    sock.on("error", () => {});
  });
  server.on("error", (e) => log(`world control: ${e.message}`));
  const old = process.umask(0o177); // the socket file is created rw------- by bind()
  try {
    server.listen(sockPath);
  } finally {
    process.umask(old);
  }
  return {
    path: sockPath,
    close() {
      server.close();
      try {
        const s = fs.lstatSync(sockPath);
        if (s.isSocket() && s.uid === process.getuid()) fs.unlinkSync(sockPath);
      } catch {}
    },
  };
}

// The server's side of the link to the CPU thread (pico_worker.mjs polls the other port between
// slices): request(req) -> Promise of the answer, or an error answer when the thread does not
// answer within timeoutMs (the RP2040 stopped).
export function workerLink(port, timeoutMs = 15000) {
  const pending = new Map();
  let next = 1;
  port.on("message", (m) => {
    const p = pending.get(m.id);
    if (!p) return;
    pending.delete(m.id);
    clearTimeout(p.timer);
    p.resolve(m.answer);
  });
  port.unref();
  return {
    request(req) {
      const id = next++;
      return new Promise((resolve) => {
        const timer = setTimeout(() => {
          pending.delete(id);
          resolve({ ok: false, error: "the virtual Pico did not answer (is it running?)" });
        }, timeoutMs);
        pending.set(id, { resolve, timer });
        port.postMessage({ id, req });
      });
    },
    close() {
      for (const p of pending.values()) clearTimeout(p.timer);
      pending.clear();
      port.close();
    },
  };
}
