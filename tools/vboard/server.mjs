#!/usr/bin/env node
// Virtual board: a MicroPython VM whose REPL is served like a board's USB
// serial port: on a pseudo-terminal (what `mpremote connect <tty> repl` needs)
// and on a loopback TCP port (pyserial/mpremote URL socket://, for exec, cp,
// run, mount; mpremote's repl cannot use it).
//
//   node tools/vboard/server.mjs [--port N] [--no-pty] [--flash DIR] [--pidfile F] ...
//   node tools/vboard/server.mjs --stop [--pidfile F]
//
// Who can reach it (docs/security.md): the pty is the starting user's (mode
// 0600); the TCP port listens on 127.0.0.1 only, for the board's whole life,
// and gives the line to one client at a time (serial_tcp.mjs).  Code on the
// board reaches no host JavaScript (vm_worker.mjs, "the sealed bridge"), writes
// only its flash directory, up to --flash-size bytes and never through a link
// (vm_files.mjs, hostdir.mjs), and uses at most --ram of memory and --ram-disk
// of in-memory files.  Input is bounded, Ctrl-C always interrupts (a VM that
// does not take it is reset), and --stop kills only this board (boardproc.mjs).
//
// Environment: BOARD_TCP (port, default 2323), MPY_WASM_DIR (the npm package
// @micropython/micropython-webassembly-pyscript), VBOARD_FLASH (flash dir),
// VBOARD_MODELS (extra dirs of device-model .py files, ':'-separated),
// VBOARD_DEVICES (the board wiring module, default vm/vboard_devices.py),
// VBOARD_SCENARIO (steady, heating, cooling, cycle: the room's temperature),
// VBOARD_TIME_SCALE (simulated seconds per board second for the profile),
// VBOARD_PROFILE (temperature profile "s:degC,s:degC,...", replacing the scenario).

import { MessageChannel, Worker } from "node:worker_threads";
import { startControl, workerLink } from "../pico/control.mjs";
import fs from "node:fs";
import path from "node:path";
import { spawn } from "node:child_process"; // the pty bridge
import { fileURLToPath } from "node:url";
import v8 from "node:v8";
import vm from "node:vm";
import { ByteQueue, CTL, Ring, makeShared } from "./rings.mjs";
import { removeOwnPidfile, runDetached, stopByPidfile, writePidfile } from "./boardproc.mjs";
import { serveSerialLine } from "./serial_tcp.mjs";

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
  --ram-disk N    in-memory files besides the flash (/tmp), bytes (default 8388608; then ENOSPC)
  --ram N         the VM's memory, bytes: its heap grows from --heap up to about this (default
                  67108864; then MemoryError)
  --idle-timeout S    a TCP client idle this long gives the line to a new one (default 30)
  --first-byte-timeout S  a TCP connection that sends nothing this long is closed (default 10)
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
    ramDisk: 8 * 1024 * 1024,
    ram: 64 * 1024 * 1024,
    idleTimeout: 30,
    firstByteTimeout: 10,
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
    else if (a === "--ram-disk") o.ramDisk = Number(val());
    else if (a === "--ram") o.ram = Number(val());
    else if (a === "--idle-timeout") o.idleTimeout = Number(val());
    else if (a === "--first-byte-timeout") o.firstByteTimeout = Number(val());
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
  if (!Number.isInteger(o.ramDisk) || o.ramDisk < 0) {
    console.error(`virtual board: --ram-disk must be a whole number of bytes, got ${o.ramDisk}`);
    process.exit(2);
  }
  if (!Number.isInteger(o.ram) || o.ram < 16 * 1024 * 1024 || o.ram > 2 ** 31) {
    console.error(`virtual board: --ram must be a whole number of bytes from 16 MiB to 2 GiB, got ${o.ram}`);
    process.exit(2);
  }
  for (const [k, flag] of [["idleTimeout", "--idle-timeout"], ["firstByteTimeout", "--first-byte-timeout"]]) {
    if (!(o[k] > 0 && o[k] <= 86400)) {
      console.error(`virtual board: ${flag} must be a number of seconds > 0, got ${o[k]}`);
      process.exit(2);
    }
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

const SERVER_SCRIPT = fileURLToPath(import.meta.url);

if (opts.stop) process.exit(stopByPidfile(opts.pidfile, SERVER_SCRIPT));

// Background start for scripts (make board-start): the same command without --detach, its
// output in a log next to the pid file; returns once the banner is out.
if (opts.detach) {
  process.exit(await runDetached({
    script: SERVER_SCRIPT,
    args: process.argv.slice(2).filter((a) => a !== "--detach"),
    logPath: opts.pidfile.replace(/\.pid$/, "") + ".log",
    stopHint: "make board-stop",
  }));
}

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
let interrupt = null; // { memory, writes, pending } for the running VM instance
let compiled = null; // the VM's WebAssembly.Module, compiled by the first worker
let powerOnMs = Date.now();
let clockUs = 0; // the board's simulated time (vboard.py), kept across resets

function configPy() {
  return (
    `# generated by tools/vboard/server.mjs at power-on\n` +
    `CLOCK_US = ${Math.max(0, Math.round(clockUs))}\n` +
    `TIME_SCALE = ${opts.timeScale}\n` +
    `SCENARIO = ${JSON.stringify(opts.scenario)}\n` +
    `PROFILE = ${JSON.stringify(opts.profile)}\n` +
    `FLASH_BYTES = ${opts.flashSize}\n`
  );
}

const WORKER_HEAP_MB = 128;

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
      ramDisk: opts.ramDisk,
      ramBytes: opts.ram,
      vmFiles,
      configPy: configPy(),
      heapsize: opts.heap,
      powerOnMs,
      compiled,
      soft,
      mode,
    },
    // the VM thread's JavaScript heap (objects board code makes through jsffi): a board that
    // exhausts it is reset, the host is not at risk
    resourceLimits: { maxOldGenerationSizeMb: WORKER_HEAP_MB },
  });
  worker = w;
  w.on("message", (m) => {
    if (w !== worker) return;
    if (m.t === "out") drainOutput();
    else if (m.t === "mem") interrupt = m.memory ? { memory: m.memory, writes: m.writes, pending: m.pending } : null;
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
    const why = e.code === "ERR_WORKER_OUT_OF_MEMORY" ? "out of memory" : "failed";
    toLine(Buffer.from(`\r\n[virtual board: the VM ${why}; resetting]\r\n`));
    hardReset();
  });
}

// The virtual Pico (tools/pico/pico_worker.mjs): the same serial rings; its firmware does
// Ctrl-C, resets and the raw REPL itself.
// The world control socket (tools/pico/control.mjs) talks to it through a message port.
let picoLink = null;
let worldControl = null;
function picoWorker() {
  fs.mkdirSync(path.dirname(opts.flash), { recursive: true });
  const { port1, port2 } = new MessageChannel();
  if (picoLink) picoLink.close();
  picoLink = workerLink(port1);
  return new Worker(path.join(REPO, "tools", "pico", "pico_worker.mjs"), {
    workerData: {
      shared,
      image: opts.flash,
      world: { scenario: opts.scenario, profile: opts.profile, timeScale: opts.timeScale },
      realtime: process.env.PICO_REALTIME !== "0",
      control: port2,
    },
    transferList: [port2],
  });
}

// machine.reset(), or a crashed VM: a new worker, as at power-on, but the
// clients stay connected (a board's USB link would drop; a serial adapter's
// would not).  Unread input is lost, as a board's UART buffer would be.
function hardReset() {
  const old = worker;
  worker = null;
  disarmWatchdog();
  if (old) old.terminate().then(collectSoon);
  inQueue.clear();
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
  disarmWatchdog();
  if (old) old.terminate().then(collectSoon);
  startWorker(true, mode);
}

function drainOutput() {
  Atomics.store(ctl, CTL.OUT_NOTIFY, 0);
  const data = outRing.read();
  Atomics.notify(ctl, CTL.OUT_R);
  if (data.length === 0) return;
  const buf = Buffer.from(data);
  toLine(buf);
}

const PTY_OUTPUT_CAP = 4 << 20;

function toLine(buf) {
  if (line) line.write(buf);
  // the bridge drops what nobody reads from the pty; this bounds what waits for the bridge
  if (ptyBridge && ptyBridge.stdin.writableLength < PTY_OUTPUT_CAP) ptyBridge.stdin.write(buf);
}

// Ctrl-C while Python runs: do what a board's UART interrupt handler does,
// set the VM's pending exception (the worker thread is busy in the VM).
function injectInterrupt() {
  if (!interrupt || !Atomics.load(ctl, CTL.BUSY)) return false;
  const words = new Uint32Array(interrupt.memory.buffer);
  for (const [addr, value] of interrupt.writes) words[addr / 4] = value;
  Atomics.add(ctl, CTL.INJECTED, 1);
  Atomics.notify(ctl, CTL.IN_W);
  injectedAt = Date.now();
  armWatchdog(CTRL_C_GRACE_MS);
  return true;
}

// The VM takes a pending KeyboardInterrupt at its next bytecode branch or call; C code that
// runs long without one (parsing or printing a 300,000-digit int: quadratic, minutes) does not
// take it.  Ctrl-C must always stop the board: if the interrupt is still pending after
// CTRL_C_GRACE_MS, the VM is reset, as its reset button would (RAM lost, flash kept).
const CTRL_C_GRACE_MS = 3000;
let watchdog = null;
let injectedAt = 0; // the latest Ctrl-C raised in the VM

function armWatchdog(ms) {
  if (watchdog || !interrupt || interrupt.pending === null || interrupt.pending === undefined) return;
  const w = worker, it = interrupt;
  watchdog = setTimeout(() => {
    watchdog = null;
    if (w !== worker || it !== interrupt || !Atomics.load(ctl, CTL.BUSY)) return;
    if (new Uint32Array(it.memory.buffer, it.pending, 1)[0] === 0) return; // taken
    const age = Date.now() - injectedAt;
    if (age < CTRL_C_GRACE_MS) return armWatchdog(CTRL_C_GRACE_MS - age); // a later Ctrl-C's turn
    console.error(`virtual board: Ctrl-C not taken within ${CTRL_C_GRACE_MS / 1000} s (the VM is in one long C call); reset`);
    toLine(Buffer.from(`\r\n[virtual board: Ctrl-C not taken within ${CTRL_C_GRACE_MS / 1000} s; resetting the board]\r\n`));
    hardReset();
  }, ms);
  watchdog.unref();
}

function disarmWatchdog() {
  if (watchdog) clearTimeout(watchdog);
  watchdog = null;
}

// Input waiting for the VM: the ring (64 KiB) and at most INPUT_CAP more; beyond, a client
// that sends faster than the board reads loses bytes, as on a board's UART (mpremote never
// does: its raw-paste mode waits for the board's flow-control window).
const INPUT_CAP = 1 << 20;
const inQueue = new ByteQueue(INPUT_CAP);
let inTimer = null;
let dropReport = null;

function feedInput(data) {
  let from = 0;
  for (;;) {
    const i = data.indexOf(3, from);
    if (i < 0) break;
    // what came before a Ctrl-C is discarded with the rest of the unread input
    ctrlC();
    from = i + 1;
  }
  if (from < data.length) inQueue.push(data.subarray(from));
  if (inQueue.dropped && !dropReport) {
    dropReport = setTimeout(() => {
      dropReport = null;
      console.error(`virtual board: input overflow: ${inQueue.dropped} bytes dropped (the board had ` +
        `${INPUT_CAP + inRing.size} unread before them)`);
      inQueue.dropped = 0;
    }, 1000);
    dropReport.unref();
  }
  flushInput();
}

// Ctrl-C: the input the board has not read is discarded and the interrupt raised, as a board's
// USB serial does (MicroPython shared/tinyusb/mp_usbd_cdc.c: "Clear the ring buffer"), so that
// Ctrl-C is never stuck behind a flood of input.  With no code running it then goes in as a key.
function ctrlC() {
  inQueue.clear();
  Atomics.store(ctl, CTL.FLUSH_TO, Atomics.load(ctl, CTL.IN_W));
  Atomics.store(ctl, CTL.FLUSH_REQ, 1);
  if (!injectInterrupt()) inQueue.push(Buffer.of(3));
}

function flushInput() {
  if (inQueue.length) {
    inQueue.drainInto(inRing);
    Atomics.notify(ctl, CTL.IN_W);
    if (worker) worker.postMessage({ t: "in" });
  }
  if (inQueue.length && !inTimer) {
    inTimer = setTimeout(() => {
      inTimer = null;
      flushInput();
    }, 5);
  }
}

// ------------------------------------------------------------ the serial line

let line = null; // the TCP port (serial_tcp.mjs)
let ptyBridge = null;

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
    removeOwnPidfile(opts.pidfile);
  } catch {}
  try {
    if (ttyLink && fs.readlinkSync(ttyLink).startsWith("/dev/")) fs.rmSync(ttyLink);
  } catch {}
  if (ptyBridge) ptyBridge.kill();
  if (worldControl) worldControl.close();
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
      (worldControl ? `  world control (host only, mode 0600): ${shown(worldControl.path)}\n` : "") +
      `  stop: Ctrl-C here, or 'make board-stop'`,
  );
}

line = serveSerialLine(
  {
    host: opts.host,
    port: opts.port,
    takeover: opts.takeover,
    idleMs: opts.idleTimeout * 1000,
    firstByteMs: opts.firstByteTimeout * 1000,
  },
  {
    input: feedInput,
    busy: () => Atomics.load(ctl, CTL.BUSY) === 1,
    log: (msg) => console.error(`virtual board: ${msg}`),
    listenError: (e) => {
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
    },
    listening: (port) => {
      writePidfile(opts.pidfile, SERVER_SCRIPT); // never through a link at that name (boardproc.mjs)
      if (opts.board === "pico") {
        worldControl = startControl(path.join(path.dirname(opts.pidfile), "world.sock"),
          (req) => picoLink.request(req), (m) => console.error(`virtual board: ${m}`));
      }
      startWorker();
      listenUrl = `socket://${opts.host}:${port}`;
      console.log(opts.board === "pico" ? `virtual Pico: RP2040 firmware listening on ${listenUrl}`
        : `virtual board: MicroPython VM listening on ${listenUrl}`);
      if (opts.pty) startPty();
      announce();
    },
  },
);
