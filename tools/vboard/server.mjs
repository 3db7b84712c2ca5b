#!/usr/bin/env node
// Virtual board: a MicroPython VM whose REPL is served like a board's USB
// serial port: on a pseudo-terminal (what `mpremote connect <tty> repl` needs)
// and on a loopback TCP port (pyserial/mpremote URL socket://, for exec, cp,
// run, mount; mpremote's repl cannot use it).
//
//   node tools/vboard/server.mjs [--port N] [--no-pty] [--flash DIR] [--pidfile F] ...
//   node tools/vboard/server.mjs --stop [--pidfile F]
//
// Who can reach it (docs/demo.md, "What the virtual board exposes"): the pty is
// the starting user's (mode 0600); the TCP port listens on 127.0.0.1 only, takes
// one client at a time (--takeover lets a new one take the line over) and
// refuses a client whose first byte is not what a terminal or mpremote sends
// (an HTTP request from a web page, TLS, ...).  Code on the board reaches no
// host JavaScript (vm_worker.mjs, "the sealed bridge") and writes only its
// flash directory, up to --flash-size bytes.
//
// Environment: BOARD_TCP (port, default 2323), MPY_WASM_DIR (the npm package
// @micropython/micropython-webassembly-pyscript), VBOARD_FLASH (flash dir),
// VBOARD_MODELS (extra dirs of device-model .py files, ':'-separated),
// VBOARD_DEVICES (the board wiring module, default vm/vboard_devices.py),
// VBOARD_SCENARIO (steady, heating, cooling, cycle: the room's temperature),
// VBOARD_TIME_SCALE (simulated seconds per board second for the profile),
// VBOARD_PROFILE (temperature profile "s:degC,s:degC,...", replacing the scenario).

import { Worker } from "node:worker_threads";
import net from "node:net";
import fs from "node:fs";
import path from "node:path";
import { execFileSync, spawn } from "node:child_process";
import { fileURLToPath } from "node:url";
import v8 from "node:v8";
import vm from "node:vm";
import { CTL, Ring, makeShared } from "./rings.mjs";

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, "..", "..");

function usage(code) {
  console.log(`usage: node tools/vboard/server.mjs [options]
  --port N        loopback TCP port (default: $BOARD_TCP or 2323; 0 picks a free one)
  --no-pty        do not serve the REPL on a pseudo-terminal (served by default)
  --tty PATH      link to the pty (default: tty next to the pid file, build/vboard/tty)
  --takeover      let a new TCP client take the line over (default: refused while one is attached)
  --scenario S    the room: steady (25 degC, default), heating, cooling or cycle (25-45-25 degC)
  --flash DIR     host directory holding the board's flash (default: build/vboard/flash)
  --flash-size N  flash size in bytes (default 2097152: a full flash refuses writes, ENOSPC)
  --pidfile F     write the server's pid here (default: build/vboard/board.pid)
  --models DIR    extra directory of device-model .py files (repeatable)
  --devices FILE  board wiring module copied in as vboard_devices.py
  --heap BYTES    initial MicroPython heap (default 262144)
  --board B       virtual (the MicroPython VM, default) or pico (the real RP2040 firmware on an
                  emulated Raspberry Pi Pico, tools/pico; flash: build/pico/flash.img, pid file
                  build/pico/board.pid)
  --detach        start in the background (log: the pid file's name with .log), return once listening
  --stop          stop the board whose pid is in --pidfile, then exit`);
  process.exit(code);
}

// vm/vboard_devices.py, SCENARIOS
const SCENARIOS = ["steady", "heating", "cooling", "cycle"];

function parseArgs(argv) {
  const env = process.env;
  const o = {
    port: env.BOARD_TCP !== undefined && env.BOARD_TCP !== "" ? Number(env.BOARD_TCP) : 2323,
    host: "127.0.0.1",
    pty: true,
    tty: "",
    takeover: false,
    scenario: env.VBOARD_SCENARIO || "steady",
    flashSize: 2 * 1024 * 1024,
    board: env.VBOARD_BOARD || "virtual",
    flash: env.VBOARD_FLASH || "",
    pidfile: "",
    models: (env.VBOARD_MODELS || "").split(":").filter(Boolean),
    devices: env.VBOARD_DEVICES || path.join(HERE, "vm", "vboard_devices.py"),
    heap: 262144,
    stop: false,
    detach: false,
    timeScale: Number(env.VBOARD_TIME_SCALE || 1),
    profile: env.VBOARD_PROFILE || "",
  };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    const val = () => {
      if (i + 1 >= argv.length) usage(2);
      return argv[++i];
    };
    if (a === "--port") o.port = Number(val());
    else if (a === "--pty") o.pty = true;
    else if (a === "--no-pty") o.pty = false;
    else if (a === "--tty") o.tty = path.resolve(val());
    else if (a === "--takeover") o.takeover = true;
    else if (a === "--scenario") o.scenario = val();
    else if (a === "--flash-size") o.flashSize = Number(val());
    else if (a === "--flash") o.flash = path.resolve(val());
    else if (a === "--pidfile") o.pidfile = path.resolve(val());
    else if (a === "--models") o.models.push(path.resolve(val()));
    else if (a === "--devices") o.devices = path.resolve(val());
    else if (a === "--heap") o.heap = Number(val());
    else if (a === "--stop") o.stop = true;
    else if (a === "--detach") o.detach = true;
    else if (a === "--board") o.board = val();
    else if (a === "-h" || a === "--help") usage(0);
    else {
      console.error(`unknown argument: ${a}`);
      usage(2);
    }
  }
  if (!Number.isInteger(o.port) || o.port < 0 || o.port > 65535) {
    console.error(`virtual board: BOARD_TCP/--port must be a port number, got ${o.port}`);
    process.exit(2);
  }
  if (!SCENARIOS.includes(o.scenario)) {
    console.error(`virtual board: unknown scenario '${o.scenario}': one of ${SCENARIOS.join(", ")}`);
    process.exit(2);
  }
  if (!Number.isInteger(o.flashSize) || o.flashSize < 65536) {
    console.error(`virtual board: --flash-size must be a whole number of bytes >= 65536, got ${o.flashSize}`);
    process.exit(2);
  }
  if (!["virtual", "pico"].includes(o.board)) {
    console.error(`virtual board: --board must be virtual or pico, got '${o.board}'`);
    process.exit(2);
  }
  const home = path.join(REPO, "build", o.board === "pico" ? "pico" : "vboard");
  if (!o.flash) o.flash = o.board === "pico" ? path.join(home, "flash.img") : path.join(home, "flash");
  if (!o.pidfile) o.pidfile = path.join(home, "board.pid");
  if (!o.tty) o.tty = path.join(path.dirname(o.pidfile), "tty");
  return o;
}

const opts = parseArgs(process.argv.slice(2));

// Who a pid is: its command line and its start time (clock ticks since boot on Linux),
// so that a pid file left by a killed board cannot name a process that reused the pid.
function procInfo(pid) {
  try {
    const stat = fs.readFileSync(`/proc/${pid}/stat`, "utf8");
    const start = stat.slice(stat.lastIndexOf(")") + 2).split(" ")[19];
    const cmd = fs.readFileSync(`/proc/${pid}/cmdline`, "utf8").split("\0").join(" ").trim();
    return { start, cmd };
  } catch {}
  try {
    // no /proc (macOS): ps gives both
    const out = execFileSync("ps", ["-o", "lstart=,command=", "-p", String(pid)], { encoding: "utf8" }).trim();
    if (!out) return null;
    return { start: out.slice(0, 24).trim(), cmd: out.slice(24).trim() };
  } catch {
    return null;
  }
}

const SERVER_SCRIPT = fileURLToPath(import.meta.url);

function writePidfile() {
  const me = procInfo(process.pid);
  fs.writeFileSync(opts.pidfile, JSON.stringify({ pid: process.pid, start: me ? me.start : null,
                                                  server: SERVER_SCRIPT }) + "\n");
}

function readPidfile() {
  const text = fs.readFileSync(opts.pidfile, "utf8").trim();
  try {
    const o = JSON.parse(text);
    if (o && Number.isInteger(o.pid) && o.pid > 0) return o;
  } catch {}
  return { pid: NaN };
}

function stopRunning() {
  let rec;
  const rel = path.relative(process.cwd(), opts.pidfile);
  try {
    rec = readPidfile();
  } catch {
    console.log(`virtual board: not running (no ${rel})`);
    return 0;
  }
  const pid = rec.pid;
  const who = Number.isInteger(pid) ? procInfo(pid) : null;
  // Only a process that is this board: the same start time and a command line running
  // this server.  Anything else (no process, a reused pid, an unreadable file) is left alone.
  if (!who || !rec.start || who.start !== rec.start || !who.cmd.includes("server.mjs")) {
    const why = !Number.isInteger(pid) ? "is not a virtual board's pid file"
      : !who ? `names pid ${pid}, which is not running`
      : `names pid ${pid}, which is now another process (${who.cmd.slice(0, 60) || "?"})`;
    console.log(`virtual board: not running: ${rel} ${why}; nothing killed, stale pid file removed`);
    fs.rmSync(opts.pidfile, { force: true });
    return 0;
  }
  try {
    process.kill(pid, "SIGTERM");
  } catch {
    console.log(`virtual board: pid ${pid} was not running; removing stale pid file`);
    fs.rmSync(opts.pidfile, { force: true });
    return 0;
  }
  const deadline = Date.now() + 5000;
  while (Date.now() < deadline) {
    try {
      process.kill(pid, 0);
      // exited, not yet reaped by its parent
      if (fs.existsSync("/proc/self") && /^\d+ \(.*\) Z/.test(fs.readFileSync(`/proc/${pid}/stat`, "utf8"))) {
        throw new Error("zombie");
      }
    } catch {
      console.log(`virtual board: stopped (pid ${pid})`);
      return 0;
    }
    Atomics.wait(new Int32Array(new SharedArrayBuffer(4)), 0, 0, 50);
  }
  console.error(`virtual board: pid ${pid} did not stop within 5 s`);
  return 1;
}

if (opts.stop) process.exit(stopRunning());

// Background start for scripts (make demo): the same command without
// --detach, detached, its output in a log; return when it is listening.
async function detach() {
  const logPath = opts.pidfile.replace(/\.pid$/, "") + ".log";
  fs.mkdirSync(path.dirname(logPath), { recursive: true });
  const log = fs.openSync(logPath, "w");
  const args = process.argv.slice(2).filter((a) => a !== "--detach");
  const child = spawn(process.execPath, [fileURLToPath(import.meta.url), ...args], {
    detached: true,
    stdio: ["ignore", log, log],
  });
  child.unref();
  const deadline = Date.now() + 15000;
  while (Date.now() < deadline) {
    const text = fs.readFileSync(logPath, "utf8");
    if (/\n {2}stop: /.test(text)) {
      process.stdout.write(text.replace(/ {2}stop: .*\n/,
        `  stop: make board-stop (running in the background, pid ${child.pid}; log: ${logPath})\n`));
      return 0;
    }
    if (child.exitCode !== null) {
      process.stderr.write(text);
      return child.exitCode || 1;
    }
    await new Promise((r) => setTimeout(r, 50));
  }
  console.error(`virtual board: did not start within 15 s; see ${logPath}`);
  return 1;
}

if (opts.detach) process.exit(await detach());

// ------------------------------------------------------------ the VM files

const wasmDir =
  process.env.MPY_WASM_DIR ||
  path.join(REPO, "tools", "node_modules", "@micropython", "micropython-webassembly-pyscript");
if (!fs.existsSync(path.join(wasmDir, "micropython.mjs"))) {
  console.error(
    `virtual board: MicroPython VM not found in ${wasmDir}\n` +
      `  install it with 'npm ci --prefix tools' (or 'make setup'), or point MPY_WASM_DIR at the\n` +
      `  @micropython/micropython-webassembly-pyscript package directory.`,
  );
  process.exit(2);
}

// Python that the VM imports at boot (never on the board's flash).
function collectVmFiles() {
  const files = {};
  const addDir = (dir) => {
    if (!fs.existsSync(dir)) {
      console.error(`virtual board: device-model directory ${dir} does not exist`);
      process.exit(2);
    }
    for (const name of fs.readdirSync(dir)) {
      if (name.endsWith(".py")) files[name] = fs.readFileSync(path.join(dir, name));
    }
  };
  addDir(path.join(HERE, "vm"));
  // The simulated parts (tools/sim) are the board's sensors: always on board.
  const sim = path.join(REPO, "tools", "sim");
  for (const name of ["mlx90609_sim.py", "mpu6xxx_sim.py", "analog_gyro_sim.py"]) {
    files[name] = fs.readFileSync(path.join(sim, name));
  }
  for (const d of opts.models) addDir(d);
  files["vboard_devices.py"] = fs.readFileSync(opts.devices);
  return files;
}

const vmFiles = collectVmFiles();
const shared = makeShared();
const ctl = new Int32Array(shared.ctl);
const inRing = new Ring(ctl, shared.inBuf, CTL.IN_W, CTL.IN_R);
const outRing = new Ring(ctl, shared.outBuf, CTL.OUT_W, CTL.OUT_R);

// ------------------------------------------------------------ the CPU

let worker = null;
let interrupt = null; // { memory, writes } for the running VM instance
let compiled = null; // the VM's WebAssembly.Module, compiled by the first worker
let powerOnMs = Date.now();
let clockUs = 0; // the board's simulated time (vboard.py), kept across resets

function configPy() {
  return (
    `# generated by tools/vboard/server.mjs at power-on\n` +
    `CLOCK_US = ${Math.max(0, Math.round(clockUs))}\n` +
    `TIME_SCALE = ${opts.timeScale}\n` +
    `SCENARIO = ${JSON.stringify(opts.scenario)}\n` +
    `PROFILE = ${JSON.stringify(opts.profile)}\n`
  );
}

function startWorker(soft = false, mode = "friendly") {
  interrupt = null;
  Atomics.store(ctl, CTL.BUSY, 0);
  // an "output ready" message of a terminated worker is never delivered: re-arm
  drainOutput();
  const w = opts.board === "pico" ? picoWorker() : new Worker(path.join(HERE, "vm_worker.mjs"), {
    workerData: {
      shared,
      wasmDir,
      flashDir: opts.flash,
      flashLimit: opts.flashSize,
      vmFiles,
      configPy: configPy(),
      heapsize: opts.heap,
      powerOnMs,
      compiled,
      soft,
      mode,
    },
  });
  worker = w;
  w.on("message", (m) => {
    if (w !== worker) return;
    if (m.t === "out") drainOutput();
    else if (m.t === "mem") interrupt = m.memory ? { memory: m.memory, writes: m.writes } : null;
    else if (m.t === "compiled") compiled = m.module;
    else if (m.t === "log") console.error(`virtual board: ${m.msg}`);
    else if (m.t === "hard-reset") {
      if (m.clockUs !== null && m.clockUs !== undefined) clockUs = m.clockUs;
      hardReset();
    } else if (m.t === "soft-reset") {
      if (m.clockUs !== null && m.clockUs !== undefined) clockUs = m.clockUs;
      softReset(m.mode);
    } else if (m.t === "fatal") shutdown(1);
  });
  w.on("error", (e) => {
    if (w !== worker) return;
    console.error(`virtual board: VM thread failed: ${e.stack || e}`);
    hardReset();
  });
}

// The virtual Pico (tools/pico/pico_worker.mjs): the same serial rings; its firmware does
// Ctrl-C, resets and the raw REPL itself.
function picoWorker() {
  fs.mkdirSync(path.dirname(opts.flash), { recursive: true });
  return new Worker(path.join(REPO, "tools", "pico", "pico_worker.mjs"), {
    workerData: {
      shared,
      image: opts.flash,
      world: { scenario: opts.scenario, profile: opts.profile, timeScale: opts.timeScale },
      realtime: process.env.PICO_REALTIME !== "0",
    },
  });
}

// machine.reset(), or a crashed VM: a new worker, as at power-on, but the
// clients stay connected (a board's USB link would drop; a serial adapter's
// would not).  Unread input is lost, as a board's UART buffer would be.
function hardReset() {
  const old = worker;
  worker = null;
  if (old) old.terminate().then(collectSoon);
  Atomics.store(ctl, CTL.IN_R, Atomics.load(ctl, CTL.IN_W));
  powerOnMs = Date.now();
  startWorker();
}

// A finished VM's memory (a SharedArrayBuffer this thread holds for Ctrl-C) is freed only
// by a collection in this thread, which allocates too little to run one by itself: without
// this, each reset keeps about 1.2 MB.
v8.setFlagsFromString("--expose-gc");
const collect = vm.runInNewContext("gc");
let collectTimer = null;
function collectSoon() {
  if (collectTimer) return;
  collectTimer = setTimeout(() => {
    collectTimer = null;
    collect();
  }, 200);
  collectTimer.unref();
}

// A soft reset: a new VM in a new worker (vm_worker.mjs, softReset), unread input kept.
function softReset(mode) {
  const old = worker;
  worker = null;
  if (old) old.terminate().then(collectSoon);
  startWorker(true, mode);
}

function drainOutput() {
  Atomics.store(ctl, CTL.OUT_NOTIFY, 0);
  const data = outRing.read();
  Atomics.notify(ctl, CTL.OUT_R);
  if (data.length === 0) return;
  const buf = Buffer.from(data);
  if (client) client.write(buf);
  if (ptyBridge) ptyBridge.stdin.write(buf);
}

// Ctrl-C while Python runs: do what a board's UART interrupt handler does,
// set the VM's pending exception (the worker thread is busy in the VM).
function injectInterrupt() {
  if (!interrupt || !Atomics.load(ctl, CTL.BUSY)) return false;
  const words = new Uint32Array(interrupt.memory.buffer);
  for (const [addr, value] of interrupt.writes) words[addr / 4] = value;
  Atomics.add(ctl, CTL.INJECTED, 1);
  Atomics.notify(ctl, CTL.IN_W);
  return true;
}

let backlog = [];
let backlogTimer = null;

function feedInput(data) {
  for (const b of data) {
    if (b === 3 && injectInterrupt()) continue;
    backlog.push(b);
  }
  flushBacklog();
}

function flushBacklog() {
  if (backlog.length) {
    const n = inRing.write(backlog);
    backlog = backlog.slice(n);
    Atomics.notify(ctl, CTL.IN_W);
    if (worker) worker.postMessage({ t: "in" });
  }
  if (backlog.length && !backlogTimer) {
    backlogTimer = setTimeout(() => {
      backlogTimer = null;
      flushBacklog();
    }, 5);
  }
}

// ------------------------------------------------------------ the serial line

let client = null;
let ptyBridge = null;

// What a serial terminal or mpremote sends first: Enter, or a control character
// (mpremote: "\r\x03").  An HTTP request (a web page's fetch or form POST to
// 127.0.0.1), TLS or any other protocol starts with a printable byte or 0x16.
const SERIAL_FIRST = new Set([1, 2, 3, 4, 5, 10, 13]);

function refuse(sock, why) {
  console.error(`virtual board: refused a client: ${why}`);
  sock.end(`\r\nvirtual board: refused: ${why}\r\n`);
  setTimeout(() => sock.destroy(), 1000).unref();
}

// One client at a time: while a connection is open the port stops listening, so a second
// one is refused by the host's TCP stack and mpremote says "failed to access socket://...
// (it may be in use by another program)"; with --takeover a new client is accepted and
// the previous one is dropped, as reopening a serial device would.
let conns = 0;
let listening = false;
let boundPort = null;

function relisten() {
  if (listening || shuttingDown || (conns > 0 && !opts.takeover)) return;
  listening = true;
  server.listen(boundPort, opts.host);
}

const server = net.createServer((sock) => {
  conns++;
  if (!opts.takeover && listening) {
    listening = false;
    server.close();
  }
  sock.setNoDelay(true);
  sock.on("error", () => {});
  let attached = false;
  let checked = false;
  sock.on("data", (d) => {
    if (!checked) {
      checked = true;
      if (!SERIAL_FIRST.has(d[0])) {
        const http = /^[A-Z]{3,8} \S+ HTTP\//.test(d.subarray(0, 200).toString("latin1"));
        return refuse(sock, http ? "an HTTP request is not a serial terminal"
          : "not a serial terminal or mpremote (a terminal's first key must be Enter)");
      }
      if (client && client !== sock) {
        client.end("\r\nvirtual board: another client took the line over (--takeover)\r\n");
      }
      client = sock;
      attached = true;
    }
    if (attached && client === sock) feedInput(d);
  });
  let gone = false;
  const bye = () => {
    if (gone) return;
    gone = true;
    conns--;
    if (client === sock) client = null;
    relisten();
  };
  sock.on("end", () => {
    if (client === sock) client = null;
    sock.end();
  });
  sock.on("close", bye);
});

server.on("error", (e) => {
  if (boundPort !== null) {
    console.error(`virtual board: cannot listen on ${opts.host}:${boundPort} again: ${e.message}; stopping`);
    return shutdown(3);
  }
  if (e.code === "EADDRINUSE") {
    console.error(
      `virtual board: port ${opts.port} on ${opts.host} is already in use.\n` +
        `  Another virtual board may be running (stop it with 'make board-stop'),\n` +
        `  or pick another port: BOARD_TCP=2324 make board  (or --port 2324).`,
    );
  } else {
    console.error(`virtual board: cannot listen on ${opts.host}:${opts.port}: ${e.message}`);
  }
  process.exit(3);
});

function startPty() {
  // Node has no pty API; a small Python helper owns the pty pair and relays.
  const py = process.env.PYTHON || "python3";
  ptyBridge = spawn(py, [path.join(HERE, "pty_bridge.py")], { stdio: ["pipe", "pipe", "inherit"] });
  ptyBridge.on("error", (e) => {
    console.error(`virtual board: no pty (${e.message}); the REPL is on the TCP port only`);
    ptyBridge = null;
    announce();
  });
  let announced = false;
  let head = Buffer.alloc(0);
  ptyBridge.stdout.on("data", (d) => {
    if (announced) return feedInput(d);
    head = Buffer.concat([head, d]);
    const nl = head.indexOf(10);
    if (nl < 0) return;
    const ptyPath = head.subarray(0, nl).toString().trim();
    announced = true;
    ttyLink = null;
    try {
      fs.rmSync(opts.tty, { force: true });
      fs.symlinkSync(ptyPath, opts.tty);
      ttyLink = opts.tty;
    } catch (e) {
      console.error(`virtual board: cannot link ${opts.tty} to the pty: ${e.message}`);
    }
    console.log(`virtual board: pty ${ptyPath}${ttyLink ? ` (linked as ${shown(ttyLink)})` : ""}`);
    ttyShown = ttyLink ? shown(ttyLink) : ptyPath;
    if (head.length > nl + 1) feedInput(head.subarray(nl + 1));
    announce();
  });
  ptyBridge.on("exit", (code) => {
    if (!shuttingDown) console.error(`virtual board: pty bridge exited (${code})`);
    ptyBridge = null;
  });
}

let ttyLink = null;
let ttyShown = null;

function shown(p) {
  const rel = path.relative(process.cwd(), p);
  return rel && !rel.startsWith("..") && !path.isAbsolute(rel) ? rel : p;
}

let shuttingDown = false;
function shutdown(code = 0) {
  if (shuttingDown) return;
  shuttingDown = true;
  try {
    if (readPidfile().pid === process.pid) fs.rmSync(opts.pidfile);
  } catch {}
  try {
    if (ttyLink && fs.readlinkSync(ttyLink).startsWith("/dev/")) fs.rmSync(ttyLink);
  } catch {}
  if (ptyBridge) ptyBridge.kill();
  process.exit(code);
}
process.on("SIGTERM", () => shutdown(0));
process.on("SIGINT", () => shutdown(0));
process.on("SIGHUP", () => shutdown(0));

let listenUrl = null;
let bannerShown = false;

// The banner, once the TCP port and the pty are both up: one line that opens the REPL.
function announce() {
  if (bannerShown || !listenUrl || (ptyBridge && !ttyShown)) return;
  bannerShown = true;
  const mb = opts.board === "pico" ? "1.38" : (opts.flashSize / 1048576).toFixed(opts.flashSize % 1048576 ? 2 : 0);
  const room = opts.profile ? `profile ${opts.profile}` : `scenario ${opts.scenario}`;
  console.log(
    (ttyShown ? `  REPL: mpremote connect ${ttyShown} repl\n` : "") +
      `  exec, cp, run, mount: mpremote connect ${listenUrl} ...` +
      (ttyShown ? "  (its repl needs the tty above)\n" : "  (no pty: --no-pty)\n") +
      `  flash: ${shown(opts.flash)} (${mb} MiB); ${room} (--scenario steady|heating|cooling|cycle)\n` +
      `  stop: Ctrl-C here, or 'make board-stop'`,
  );
}

server.once("listening", () => {
  const port = server.address().port;
  boundPort = port;
  fs.mkdirSync(path.dirname(opts.pidfile), { recursive: true });
  writePidfile();
  startWorker();
  listenUrl = `socket://${opts.host}:${port}`;
  console.log(opts.board === "pico" ? `virtual Pico: RP2040 firmware listening on ${listenUrl}`
    : `virtual board: MicroPython VM listening on ${listenUrl}`);
  if (opts.pty) startPty();
  announce();
});
listening = true;
server.listen(opts.port, opts.host);
