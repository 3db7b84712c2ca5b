#!/usr/bin/env node
// Virtual board: a MicroPython VM whose REPL is served like a board's USB
// serial port, on a loopback TCP port (pyserial/mpremote URL socket://) and
// optionally on a pseudo-terminal.
//
//   node tools/vboard/server.mjs [--port N] [--pty] [--flash DIR] [--pidfile F]
//   node tools/vboard/server.mjs --stop [--pidfile F]
//
// Environment: BOARD_TCP (port, default 2323), MPY_WASM_DIR (the npm package
// @micropython/micropython-webassembly-pyscript), VBOARD_FLASH (flash dir),
// VBOARD_MODELS (extra dirs of device-model .py files, ':'-separated),
// VBOARD_DEVICES (the board wiring module, default vm/vboard_devices.py),
// VBOARD_TIME_SCALE (simulated seconds per real second for the profile),
// VBOARD_PROFILE (temperature profile "s:degC,s:degC,...", replacing the wiring's).

import { Worker } from "node:worker_threads";
import net from "node:net";
import fs from "node:fs";
import path from "node:path";
import { spawn } from "node:child_process";
import { fileURLToPath } from "node:url";
import { CTL, Ring, makeShared } from "./rings.mjs";

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, "..", "..");

function usage(code) {
  console.log(`usage: node tools/vboard/server.mjs [options]
  --port N        loopback TCP port (default: $BOARD_TCP or 2323; 0 picks a free one)
  --pty           also serve the REPL on a pseudo-terminal (path printed at start)
  --flash DIR     host directory holding the board's flash (default: build/vboard/flash)
  --pidfile F     write the server's pid here (default: build/vboard/board.pid)
  --models DIR    extra directory of device-model .py files (repeatable)
  --devices FILE  board wiring module copied in as vboard_devices.py
  --heap BYTES    initial MicroPython heap (default 262144)
  --detach        start in the background (log: the pid file's name with .log), return once listening
  --stop          stop the board whose pid is in --pidfile, then exit`);
  process.exit(code);
}

function parseArgs(argv) {
  const env = process.env;
  const o = {
    port: env.BOARD_TCP !== undefined && env.BOARD_TCP !== "" ? Number(env.BOARD_TCP) : 2323,
    host: "127.0.0.1",
    pty: false,
    flash: env.VBOARD_FLASH || path.join(REPO, "build", "vboard", "flash"),
    pidfile: path.join(REPO, "build", "vboard", "board.pid"),
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
    else if (a === "--flash") o.flash = path.resolve(val());
    else if (a === "--pidfile") o.pidfile = path.resolve(val());
    else if (a === "--models") o.models.push(path.resolve(val()));
    else if (a === "--devices") o.devices = path.resolve(val());
    else if (a === "--heap") o.heap = Number(val());
    else if (a === "--stop") o.stop = true;
    else if (a === "--detach") o.detach = true;
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
  return o;
}

const opts = parseArgs(process.argv.slice(2));

function stopRunning() {
  let pid;
  try {
    pid = Number(fs.readFileSync(opts.pidfile, "utf8").trim());
  } catch {
    console.log(`virtual board: not running (no ${path.relative(process.cwd(), opts.pidfile)})`);
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
    if (/listening on socket:/.test(text) && (!opts.pty || /pty \/dev/.test(text))) {
      process.stdout.write(text);
      console.log(`  (running in the background, pid ${child.pid}; log: ${logPath})`);
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
const serverStartMs = Date.now();
let powerOnMs = serverStartMs;

function configPy() {
  return (
    `# generated by tools/vboard/server.mjs at power-on\n` +
    `TICKS_OFFSET_MS = ${powerOnMs - serverStartMs}\n` +
    `TIME_SCALE = ${opts.timeScale}\n` +
    `PROFILE = ${JSON.stringify(opts.profile)}\n`
  );
}

function startWorker() {
  interrupt = null;
  Atomics.store(ctl, CTL.BUSY, 0);
  const w = new Worker(path.join(HERE, "vm_worker.mjs"), {
    workerData: {
      shared,
      wasmDir,
      flashDir: opts.flash,
      vmFiles,
      configPy: configPy(),
      heapsize: opts.heap,
      powerOnMs,
    },
  });
  worker = w;
  w.on("message", (m) => {
    if (w !== worker) return;
    if (m.t === "out") drainOutput();
    else if (m.t === "mem") interrupt = m.memory ? { memory: m.memory, writes: m.writes } : null;
    else if (m.t === "log") console.error(`virtual board: ${m.msg}`);
    else if (m.t === "hard-reset") hardReset();
    else if (m.t === "fatal") shutdown(1);
  });
  w.on("error", (e) => {
    if (w !== worker) return;
    console.error(`virtual board: VM thread failed: ${e.stack || e}`);
    hardReset();
  });
}

// machine.reset(), or a crashed VM: a new worker, as at power-on, but the
// clients stay connected (a board's USB link would drop; a serial adapter's
// would not).  Unread input is lost, as a board's UART buffer would be.
function hardReset() {
  const old = worker;
  worker = null;
  if (old) old.terminate();
  Atomics.store(ctl, CTL.IN_R, Atomics.load(ctl, CTL.IN_W));
  powerOnMs = Date.now();
  startWorker();
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

const server = net.createServer((sock) => {
  sock.setNoDelay(true);
  // One port, one host: a new connection takes the line over, as reopening
  // a serial device would.
  if (client) client.destroy();
  client = sock;
  sock.on("data", (d) => {
    if (client === sock) feedInput(d);
  });
  sock.on("error", () => {});
  sock.on("close", () => {
    if (client === sock) client = null;
  });
});

server.on("error", (e) => {
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
  let announced = false;
  let head = Buffer.alloc(0);
  ptyBridge.stdout.on("data", (d) => {
    if (announced) return feedInput(d);
    head = Buffer.concat([head, d]);
    const nl = head.indexOf(10);
    if (nl < 0) return;
    const ptyPath = head.subarray(0, nl).toString().trim();
    announced = true;
    console.log(`virtual board: pty ${ptyPath}   (mpremote connect ${ptyPath})`);
    if (head.length > nl + 1) feedInput(head.subarray(nl + 1));
  });
  ptyBridge.on("exit", (code) => {
    if (!shuttingDown) console.error(`virtual board: pty bridge exited (${code})`);
    ptyBridge = null;
  });
}

let shuttingDown = false;
function shutdown(code = 0) {
  if (shuttingDown) return;
  shuttingDown = true;
  try {
    if (Number(fs.readFileSync(opts.pidfile, "utf8")) === process.pid) fs.rmSync(opts.pidfile);
  } catch {}
  if (ptyBridge) ptyBridge.kill();
  process.exit(code);
}
process.on("SIGTERM", () => shutdown(0));
process.on("SIGINT", () => shutdown(0));
process.on("SIGHUP", () => shutdown(0));

server.listen(opts.port, opts.host, () => {
  const port = server.address().port;
  fs.mkdirSync(path.dirname(opts.pidfile), { recursive: true });
  fs.writeFileSync(opts.pidfile, `${process.pid}\n`);
  startWorker();
  if (opts.pty) startPty();
  console.log(
    `virtual board: MicroPython VM listening on socket://${opts.host}:${port}\n` +
      `  flash: ${opts.flash}\n` +
      `  connect: mpremote connect socket://${opts.host}:${port} repl\n` +
      `  stop: Ctrl-C here, or 'make board-stop'`,
  );
});
