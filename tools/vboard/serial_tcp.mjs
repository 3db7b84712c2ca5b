// A board's serial line on a loopback TCP port (what mpremote's socket:// URL reaches), with
// the policy of who gets it.  Shared by the board front ends (server.mjs; the RP2040 board
// reuses it).
//
// - The port is bound once and listens for the board's whole life.  Closing it while a client
//   is attached (to have the kernel refuse a second one) would let any local process bind the
//   port in between and receive the user's next `mpremote exec`, the code being deployed.
// - One client has the line at a time.  A connection is "attached" once its first byte shows
//   a terminal or mpremote (Enter or a control character); an HTTP request (any web page can
//   send one to 127.0.0.1), TLS or another protocol is refused before anything reaches the
//   board.  While one is attached, a new connection waits up to `graceMs` for it to leave (the
//   previous mpremote's close may not be read yet) and is then refused, with a message; with
//   `takeover` it takes the line over instead.
// - A connection that sends nothing does not hold the line: unattached connections are closed
//   after `firstByteMs` without a byte, at most `maxPending` wait at once (the oldest goes).
// - An attached client that has been idle (no byte either way, the board not running code) for
//   `idleMs` gives the line up to a new client instead of locking it out.
// - Output to a client that does not read is dropped beyond `outputCap` buffered bytes (a board's
//   UART drops as well) instead of filling the host's memory.

import net from "node:net";

// What a serial terminal or mpremote sends first: Enter, or a control character (mpremote:
// "\r\x03").  An HTTP request, TLS or any other protocol starts with a printable byte or 0x16.
export const SERIAL_FIRST = new Set([1, 2, 3, 4, 5, 10, 13]);

export const DEFAULTS = {
  name: "virtual board", // in the messages a refused or closed client reads
  host: "127.0.0.1",
  takeover: false,
  graceMs: 2000,
  firstByteMs: 10000,
  idleMs: 30000,
  maxPending: 8,
  outputCap: 4 << 20,
};

// hooks: input(buf) for bytes from the attached client; busy() true while the board runs code;
// listening(port) once bound; log(msg) for the server's log.  Returns { write(buf), port() }.
export function serveSerialLine(options, hooks) {
  const o = { ...DEFAULTS, ...options };
  const log = hooks.log || ((m) => console.error(m));
  const busy = hooks.busy || (() => false);

  let client = null; // the attached socket
  let lastActivity = 0; // of the attached client
  const pending = []; // connected, no byte yet
  let waiter = null; // a new connection waiting for the attached client to leave
  let dropped = 0;
  let lingering = 0; // refused sockets still being closed

  const touch = () => {
    lastActivity = Date.now();
  };
  // running code is not idleness: sample it, so that a long silent computation keeps the line
  const sampler = setInterval(() => {
    if (client && busy()) touch();
  }, 1000);
  sampler.unref();

  function say(sock, text) {
    if (!sock.destroyed) sock.end(`\r\n${o.name}: ${text}\r\n`);
    const t = setTimeout(() => sock.destroy(), 1000);
    t.unref();
    sock.once("close", () => clearTimeout(t));
  }

  function refuse(sock, why) {
    log(`refused a client: ${why}`);
    if (lingering > 64) return sock.destroy(); // a flood: no goodbye for each
    lingering++;
    sock.once("close", () => lingering--);
    say(sock, `refused: ${why}`);
  }

  function unpend(sock) {
    const i = pending.indexOf(sock);
    if (i >= 0) pending.splice(i, 1);
  }

  function detach(sock, text) {
    if (client !== sock) return;
    client = null;
    if (text) say(sock, text);
    if (waiter) {
      const w = waiter;
      waiter = null;
      clearTimeout(w.timer);
      admit(w.sock);
      w.sock.resume();
    }
  }

  function idleFor() {
    return busy() ? 0 : Date.now() - lastActivity;
  }

  // a connection that may become the client: its first byte decides
  function admit(sock) {
    pending.push(sock);
    if (pending.length > o.maxPending) {
      const oldest = pending.shift();
      say(oldest, "closed: too many connections waiting to send their first byte");
    }
    const timer = setTimeout(() => {
      if (pending.includes(sock)) {
        unpend(sock);
        log(`closed a client that sent nothing within ${o.firstByteMs / 1000} s`);
        say(sock, `closed: nothing received within ${o.firstByteMs / 1000} s`);
      }
    }, o.firstByteMs);
    timer.unref();
    sock.once("close", () => clearTimeout(timer));
  }

  function firstByte(sock, d) {
    unpend(sock);
    if (!SERIAL_FIRST.has(d[0])) {
      const http = /^[A-Z]{3,8} \S+ HTTP\//.test(d.subarray(0, 200).toString("latin1"));
      refuse(sock, http ? "an HTTP request is not a serial terminal"
        : "not a serial terminal or mpremote (a terminal's first key must be Enter)");
      return false;
    }
    if (client && client !== sock) {
      if (o.takeover) {
        detach(client, "another client took the line over (--takeover)");
      } else {
        // a connection admitted while the line was free, beaten to it by another
        refuse(sock, "another client has the line");
        return false;
      }
    }
    client = sock;
    touch();
    return true;
  }

  const server = net.createServer((sock) => {
    sock.setNoDelay(true);
    sock.on("error", () => {});
    let attached = false;
    let checked = false;
    sock.on("data", (d) => {
      if (!checked) {
        checked = true;
        attached = firstByte(sock, d);
      }
      if (attached && client === sock) {
        touch();
        hooks.input(d);
      }
    });
    sock.on("end", () => {
      detach(sock);
      sock.end();
    });
    sock.on("close", () => {
      unpend(sock);
      if (waiter && waiter.sock === sock) {
        clearTimeout(waiter.timer);
        waiter = null;
      }
      detach(sock);
    });

    if (!client || o.takeover) return admit(sock);
    const idle = idleFor();
    if (idle >= o.idleMs) {
      log(`gave the line to a new client: the attached one was idle for ${Math.round(idle / 1000)} s`);
      detach(client, `closed: idle for ${Math.round(idle / 1000)} s and another client wants the line`);
      return admit(sock);
    }
    if (waiter) return refuse(sock, "another client has the line");
    // the attached client may be on its way out (its close not read yet): wait a moment
    sock.pause();
    const timer = setTimeout(() => {
      if (waiter && waiter.sock === sock) {
        waiter = null;
        refuse(sock, "another client has the line");
      }
    }, o.graceMs);
    timer.unref();
    waiter = { sock, timer };
  });

  let boundPort = null;
  server.on("error", (e) => {
    if (boundPort === null) return hooks.listenError(e);
    // the listening socket stays open: an accept that failed (EMFILE...) costs one connection
    log(`TCP port ${boundPort}: ${e.message}; still listening`);
  });
  server.once("listening", () => {
    boundPort = server.address().port;
    hooks.listening(boundPort);
  });
  server.listen(o.port, o.host);

  return {
    write(buf) {
      const c = client;
      if (!c || c.destroyed) return;
      if (c.writableLength > o.outputCap) {
        if (dropped === 0) log(`output to a client that does not read is being dropped (over ${o.outputCap} bytes buffered)`);
        dropped += buf.length;
        return;
      }
      dropped = 0;
      touch();
      c.write(buf);
    },
    port: () => boundPort,
  };
}
