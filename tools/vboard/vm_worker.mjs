// The virtual board's CPU: one MicroPython WebAssembly VM in a worker thread.
//
// The server thread owns the serial line (TCP / pty); this thread owns the VM
// and speaks the board's side of the REPL protocol.  Friendly-REPL characters
// are handed to the VM's own event-driven REPL (readline, auto-indent, paste
// mode are the real thing).  The raw REPL is implemented here instead: the VM
// can run it, but its raw-paste reader calls mp_hal_stdin_rx_chr(), which the
// WebAssembly port defines as a constant 0, so a raw-paste request (what
// mpremote sends first) would spin forever inside the VM.  Code received over
// the raw REPL is run with the VM's runPython(), framed exactly as
// shared/runtime/pyexec.c frames it on a board.

import { parentPort, workerData } from "node:worker_threads";
import fs from "node:fs";
import path from "node:path";
import { pathToFileURL } from "node:url";
import { CTL, Ring } from "./rings.mjs";
import { FLASH, installFiles } from "./vm_files.mjs";

const { shared, wasmDir, flashDir, vmFiles, configPy, heapsize, powerOnMs, compiled, flashLimit, ramDisk, ramBytes } =
  workerData;
const ctl = new Int32Array(shared.ctl);
const inRing = new Ring(ctl, shared.inBuf, CTL.IN_W, CTL.IN_R);
const outRing = new Ring(ctl, shared.outBuf, CTL.OUT_W, CTL.OUT_R);

const CTRL_A = 1, CTRL_B = 2, CTRL_C = 3, CTRL_D = 4, CTRL_E = 5;
const RAW_BANNER = "raw REPL; CTRL-B to exit\r\n>";
// Raw-paste flow-control window.  Boards use half their stdin buffer (128 on
// most ports); the host has no such limit, and a window that holds one of
// mpremote's 256-byte file chunks avoids a round trip per chunk.
const PASTE_WINDOW = 512;
const PYEXEC_FORCED_EXIT = 0x100;

function log(msg) {
  parentPort.postMessage({ t: "log", msg });
}

// ---------------------------------------------------------------- output

let suppressOutput = false;
let lastWasCR = false;
let captured = "";

function notifyOut() {
  if (Atomics.compareExchange(ctl, CTL.OUT_NOTIFY, 0, 1) === 0) {
    parentPort.postMessage({ t: "out" });
  }
}

function emitBytes(bytes) {
  if (suppressOutput) return;
  captured = (captured + Buffer.from(bytes).toString("latin1")).slice(-64);
  let i = 0;
  while (i < bytes.length) {
    i += outRing.write(bytes, i);
    notifyOut();
    if (i < bytes.length) {
      // Ring full: the server drains it even with no client attached, so this
      // only waits for the other thread to catch up.
      Atomics.wait(ctl, CTL.OUT_R, Atomics.load(ctl, CTL.OUT_R), 50);
    }
  }
}

// Boards send "\r\n" for every "\n" that Python prints (stdout is "cooked").
function emitCooked(bytes) {
  const out = [];
  for (const b of bytes) {
    if (b === 10 && !lastWasCR) out.push(13);
    out.push(b);
    lastWasCR = b === 13;
  }
  emitBytes(Uint8Array.from(out));
}

function emitText(s) {
  emitCooked(Buffer.from(s, "utf8"));
}

function emitRaw(s) {
  const b = Buffer.from(s, "latin1");
  if (b.length) lastWasCR = b[b.length - 1] === 13;
  emitBytes(b);
}

// ---------------------------------------------------------------- the VM

let wasmModule = null; // compiled once per worker, instantiated per soft reset
let memory = null;
let ticksSpins = 0;
let ticksLast = -1;

// Three changes to the VM as loaded, all at instantiation and none touching
// the package on disk:
// - its linear memory is declared shared, so that the server thread can raise
//   KeyboardInterrupt in code that never calls out of the VM (a bare
//   `while True: pass`), exactly as a UART interrupt handler does on a board;
// - that memory's maximum is the board's RAM (--ram): the MicroPython heap grows
//   from --heap on demand (the port adds heap areas when full), and the build
//   allows 2 GiB, all of it the host process's; beyond --ram board code gets
//   MemoryError, as on a board;
// - ticks_ms counts from power-on (not from each soft reset, as the stock
//   import does) and a busy-wait on it (time.sleep is one) gives the CPU back.
function makeMemoryShared(bytes, maxBytes) {
  const b = new Uint8Array(bytes);
  const leb = (p) => {
    let v = 0, s = 0, x;
    do { x = b[p++]; v |= (x & 0x7f) << s; s += 7; } while (x & 0x80);
    return [v >>> 0, p];
  };
  const toLeb = (v) => {
    const out = [];
    do {
      let x = v & 0x7f;
      v >>>= 7;
      if (v) x |= 0x80;
      out.push(x);
    } while (v);
    return out;
  };
  let p = 8;
  while (p < b.length) {
    const id = b[p];
    const [size, body] = leb(p + 1);
    if (id === 5) {
      // One memory, flags 1 = "has maximum"; shared memories need a maximum (flags 3).
      if (b[body] !== 1 || b[body + 1] !== 1) return null;
      const [initial, q] = leb(body + 2);
      const [max] = leb(q);
      const pages = Math.max(initial, Math.min(max, Math.ceil(maxBytes / 65536)));
      const section = [1, 3, ...toLeb(initial), ...toLeb(pages)];
      const out = new Uint8Array(b.length - size + section.length + 8);
      const head = [5, ...toLeb(section.length)];
      out.set(b.subarray(0, p), 0);
      out.set(head, p);
      out.set(section, p + head.length);
      out.set(b.subarray(body + size), p + head.length + section.length);
      return out.subarray(0, p + head.length + section.length + (b.length - body - size));
    }
    p = body + size;
  }
  return null;
}

// The VM's libc reports file errors with WASI errno numbers (ENOENT is 44)
// and MicroPython passes them on unchanged, while MicroPython code and tools
// (mpremote decodes "[Errno 2] ENOENT") expect the Linux numbers a board uses.
// Translate at the syscall boundary.
const WASI_TO_LINUX = [
  0, 7, 13, 98, 99, 97, 11, 114, 9, 74, 16, 125, 10, 103, 111, 104, 35, 89, 33, 122,
  17, 14, 27, 113, 43, 84, 115, 4, 22, 5, 106, 21, 40, 24, 31, 90, 72, 36, 100, 102,
  101, 23, 105, 19, 2, 8, 37, 67, 12, 42, 92, 28, 38, 107, 20, 39, 131, 88, 95, 25,
  6, 75, 130, 1, 32, 71, 93, 91, 34, 30, 29, 3, 116, 110, 26, 18, 1,
];
const linuxErrno = (e) => (e > 0 && e < WASI_TO_LINUX.length ? WASI_TO_LINUX[e] : e);

function mapSyscallErrors(imports) {
  for (const ns of Object.values(imports)) {
    if (ns.__mapped) continue;
    for (const name of Object.keys(ns)) {
      const f = ns[name];
      if (typeof f !== "function") continue;
      if (name.startsWith("__syscall_")) {
        ns[name] = (...a) => {
          const r = f(...a);
          return typeof r === "number" && r < 0 ? -linuxErrno(-r) : r;
        };
      } else if (name.startsWith("fd_")) {
        ns[name] = (...a) => {
          const r = f(...a);
          return typeof r === "number" && r > 0 ? linuxErrno(r) : r;
        };
      }
    }
    ns.__mapped = true;
  }
}

// A clock jump that ends both the ms and the us (ms * 1000) busy-waits: half
// the 32-bit range or more in both units.
const SLEEP_BREAK_MS = (() => {
  for (let j = 2 ** 31; ; j++) {
    if (j % 2 ** 32 >= 2 ** 31 && (j * 1000) % 2 ** 32 >= 2 ** 31) return j;
  }
})();

const origInstantiate = WebAssembly.instantiate;
WebAssembly.instantiate = async function (source, imports) {
  if (!(source instanceof WebAssembly.Module) && imports?.env?.mp_js_ticks_ms) {
    if (!wasmModule && compiled) wasmModule = compiled;
    if (!wasmModule) {
      const patched = makeMemoryShared(source, ramBytes);
      if (!patched) log("warning: could not make VM memory shared; Ctrl-C cannot stop a tight loop");
      wasmModule = await WebAssembly.compile(patched || source);
      // compiled once per server: the next workers (soft resets) reuse it
      parentPort.postMessage({ t: "compiled", module: wasmModule });
    }
    imports.env.mp_js_ticks_ms = () => {
      const t = (Date.now() - powerOnMs) >>> 0;
      // time.sleep() busy-waits on this clock without checking for Ctrl-C;
      // while an interrupt is pending, jump the clock so the wait ends and
      // the VM raises KeyboardInterrupt, as a board's sleep does.
      if (kbd && pendingInterrupt()) return (t + SLEEP_BREAK_MS) >>> 0;
      if (t === ticksLast) {
        if (++ticksSpins > 200) {
          Atomics.wait(ctl, CTL.NAP, 0, 1);
          ticksSpins = 0;
        }
      } else {
        ticksLast = t;
        ticksSpins = 0;
      }
      return t;
    };
    mapSyscallErrors(imports);
    // growth past --ram fails without the glue's error message for each attempt (the heap
    // grows by doubling, so it stops between half of --ram and all of it)
    const resize = imports.env.emscripten_resize_heap;
    if (typeof resize === "function" && !resize.__capped) {
      imports.env.emscripten_resize_heap = (size) => ((size >>> 0) > ramBytes ? 0 : resize(size));
      imports.env.emscripten_resize_heap.__capped = true;
    }
    // `obj.attr = v` from Python on a frozen object (freezeIntrinsics) does nothing, as in
    // sloppy JavaScript, instead of throwing through the VM's C frames
    const storeAttr = imports.env.store_attr;
    if (typeof storeAttr === "function" && !storeAttr.__wrapped) {
      imports.env.store_attr = (...a) => {
        try {
          return storeAttr(...a);
        } catch (e) {
          if (!(e instanceof TypeError)) throw e;
        }
      };
      imports.env.store_attr.__wrapped = true;
    }
    const instance = await origInstantiate(wasmModule, imports);
    memory = instance.exports.memory;
    return { instance, module: wasmModule };
  }
  return origInstantiate(source, imports);
};

const { loadMicroPython } = await import(pathToFileURL(path.join(wasmDir, "micropython.mjs")).href);

// ------------------------------------------------------------ the sealed bridge

// Code on the board reaches JavaScript through the VM's `js` module (and jsffi), whose root is
// the JS global object: in this worker that is node's, with process, require and fs one step
// away, i.e. the host.  The board gets this object as its `js` instead: the few calls the board
// itself needs, nothing else.  From a function the only way onwards is .constructor, to
// Function (code from a string, in this realm's global scope), so the function prototypes'
// constructor properties are taken away too (nothing here or in the VM's loader uses them).
let resetRequested = false;
const BRIDGE = Object.freeze(
  Object.assign(Object.create(null), {
    // machine.reset()
    vboard_reset: () => {
      resetRequested = true;
    },
  }),
);

for (const f of [function () {}, async function () {}, function* () {}, async function* () {}]) {
  Object.defineProperty(Object.getPrototypeOf(f), "constructor", {
    value: undefined,
    writable: false,
    configurable: false,
  });
}

// ... and the shared prototypes cannot be changed from the board either: a getter planted on
// Object.prototype (a Python function, through jsffi) would otherwise be called by this
// worker's own code with its objects - the VM's loader, FS - as `this`.
function freezeIntrinsics() {
  const ctors = [Object, Function, Array, Promise, Error, TypeError, RangeError, SyntaxError,
    ReferenceError, EvalError, URIError, AggregateError, Map, Set, WeakMap, WeakSet, WeakRef,
    FinalizationRegistry, RegExp, String, Number, Boolean, Symbol, BigInt, Date, ArrayBuffer,
    SharedArrayBuffer, DataView, Proxy, Reflect, JSON, Math, Atomics, WebAssembly,
    Object.getPrototypeOf(Uint8Array)];
  const typed = [Int8Array, Uint8Array, Uint8ClampedArray, Int16Array, Uint16Array, Int32Array,
    Uint32Array, Float32Array, Float64Array, BigInt64Array, BigUint64Array];
  const protos = [Object.getPrototypeOf(function* () {}), Object.getPrototypeOf(async function () {}),
    Object.getPrototypeOf(async function* () {}), Object.getPrototypeOf([][Symbol.iterator]()),
    Object.getPrototypeOf(Object.getPrototypeOf([][Symbol.iterator]()))];
  // A frozen prototype's data property cannot be shadowed by assignment on an instance
  // (`this.name = ...` in an Error subclass would throw): turn the ones code assigns into
  // accessors whose setter defines the instance's own property, then freeze.
  const shadowable = ["name", "message", "toString", "valueOf", "stack", "code"];
  const freeze = (o) => {
    for (const k of shadowable) {
      const d = Object.getOwnPropertyDescriptor(o, k);
      if (!d || !("value" in d) || !d.configurable) continue;
      const value = d.value;
      Object.defineProperty(o, k, {
        get() {
          return value;
        },
        set(v) {
          if (this === o) throw new TypeError(`cannot change a sealed prototype's ${k}`);
          Object.defineProperty(this, k, { value: v, writable: true, enumerable: false, configurable: true });
        },
        enumerable: d.enumerable,
        configurable: false,
      });
    }
    Object.freeze(o);
  };
  for (const c of [...ctors, ...typed]) {
    freeze(c);
    if (c.prototype) freeze(c.prototype);
  }
  for (const p of protos) freeze(p);
}

function sealBridge() {
  // proxy_js_ref[0] is what `import js` proxies (MP_OBJ_JSPROXY_REF_GLOBAL_THIS)
  const refs = globalThis.proxy_js_ref;
  const map = globalThis.proxy_js_ref_map;
  if (!Array.isArray(refs) || refs[0] !== globalThis || !(map instanceof Map)) {
    throw new Error("unexpected VM build: cannot seal its js bridge");
  }
  refs[0] = BRIDGE;
  map.delete(globalThis);
  map.set(BRIDGE, 0);
}

let mp = null;
let FS = null;
let kbd = null; // { pending, writes } found by watching mp_sched_keyboard_interrupt

// Find the words mp_sched_keyboard_interrupt() writes (the pending-exception
// slot and the scheduler state), then undo them.  The server replays the same
// writes from its own thread to interrupt running code.
function discoverInterrupt(M) {
  if (!(memory.buffer instanceof SharedArrayBuffer)) return null;
  const span = Math.min(memory.buffer.byteLength, 4 << 20);
  const before = new Uint32Array(memory.buffer.slice(0, span));
  M._mp_sched_keyboard_interrupt();
  const after = new Uint32Array(memory.buffer, 0, span / 4);
  const writes = [];
  for (let i = 0; i < before.length; i++) {
    if (before[i] !== after[i]) writes.push([i * 4, after[i], before[i]]);
  }
  for (const [addr, , old] of writes) after[addr / 4] = old;
  // Expect the exception pointer (to the VM's static KeyboardInterrupt
  // instance) and the scheduler flag; anything else means an unknown build.
  const ptrs = writes.filter(([, v]) => v !== 0 && v < span);
  if (writes.length !== 2 || ptrs.length !== 1) {
    log(`warning: unexpected interrupt layout ${JSON.stringify(writes)}; Ctrl-C limited`);
    return null;
  }
  const [pendingAddr, excAddr] = ptrs[0];
  const sched = writes.find((w) => w !== ptrs[0]);
  // mp_sched_keyboard_interrupt also clears the exception's traceback pointer
  // (mp_obj_exception_t: base, packed alloc/len, traceback_data, args).
  return {
    pending: pendingAddr,
    writes: [[excAddr + 8, 0], [pendingAddr, excAddr], [sched[0], sched[1]]],
  };
}

function pendingInterrupt() {
  return kbd ? new Uint32Array(memory.buffer, kbd.pending, 1)[0] !== 0 : false;
}

function clearPendingInterrupt() {
  if (kbd) new Uint32Array(memory.buffer, kbd.pending, 1)[0] = 0;
}

// Ctrl-C on the line discards the input the board has not read (the server asks, this thread
// does it: only the reader moves the read index), as a board's USB serial does.
function applyFlush() {
  if (Atomics.exchange(ctl, CTL.FLUSH_REQ, 0) === 0) return;
  const to = Atomics.load(ctl, CTL.FLUSH_TO);
  if (((to - Atomics.load(ctl, CTL.IN_R)) | 0) > 0) Atomics.store(ctl, CTL.IN_R, to);
}

// stdin for running Python code (sys.stdin, input()): block until a byte
// arrives; return 0 bytes (EOF) if Ctrl-C was injected meanwhile so that the
// pending KeyboardInterrupt gets raised.
function stdinRead(stream, buffer, offset, length) {
  applyFlush();
  while (inRing.available() === 0) {
    if (pendingInterrupt()) return 0;
    Atomics.wait(ctl, CTL.IN_W, Atomics.load(ctl, CTL.IN_W), 100);
    applyFlush();
  }
  const data = inRing.read(length);
  for (let i = 0; i < data.length; i++) buffer[offset + i] = data[i];
  return data.length;
}

function stdoutWrite(stream, buffer, offset, length) {
  emitCooked(new Uint8Array(buffer.buffer, buffer.byteOffset + offset, length).slice());
  return length;
}

// ------------------------------------------------------------ boot

const SETUP = `
def _vboard_setup():
    import sys, vfs, os
    vfs.mount(vfs.VfsPosix('/vboard'), '/_vboard')
    sys.path.insert(0, '/_vboard')
    try:
        import vboard_rt
        vboard_rt.start()
    finally:
        sys.path.remove('/_vboard')
        vfs.umount('/_vboard')
        os.chdir('/')
_vboard_setup()
del _vboard_setup
`;

let mode = workerData.mode || "friendly";

function setBusy(on) {
  Atomics.store(ctl, CTL.BUSY, on ? 1 : 0);
}

// A Ctrl-C that reached the line just before the code started (the server saw the VM idle
// and queued it as a byte) interrupts the code, as a board's UART interrupt would have:
// input up to it is dropped.
function ctrlCWaiting() {
  if (!kbd) return;
  applyFlush();
  const n = inRing.available();
  if (n === 0) return;
  const r = Atomics.load(ctl, CTL.IN_R);
  const buf = new Uint8Array(shared.inBuf);
  for (let i = 0; i < n; i++) {
    if (buf[(r + i) & (buf.length - 1)] === CTRL_C) {
      Atomics.store(ctl, CTL.IN_R, (r + i + 1) | 0);
      const words = new Uint32Array(memory.buffer);
      for (const [addr, value] of kbd.writes) words[addr / 4] = value;
      return;
    }
  }
}

// Runs Python source with Ctrl-C armed; returns the PythonError or null.
function runCode(code, early = true) {
  clearPendingInterrupt();
  setBusy(true);
  if (early) ctrlCWaiting();
  let err = null;
  try {
    mp.runPython(code);
  } catch (e) {
    err = e;
  } finally {
    setBusy(false);
  }
  // A Ctrl-C that arrived as the code finished must not hit the next command.
  clearPendingInterrupt();
  if (err && err.name !== "PythonError") throw err;
  return err;
}

function printError(err) {
  if (err && err.type !== "SystemExit") emitText(err.message);
}

async function bootVM() {
  mp = await loadMicroPython({
    heapsize,
    stdin: () => null,
    stdout: () => {},
    stderr: () => {},
    linebuffer: false,
  });
  sealBridge();
  freezeIntrinsics();
  FS = mp.FS;
  const M = mp._module;
  for (const fd of [0, 1, 2]) {
    const stream = FS.getStream(fd);
    const ops = fd === 0 ? { read: stdinRead } : { write: stdoutWrite };
    Object.assign(stream.stream_ops, ops);
  }
  kbd = discoverInterrupt(M);
  parentPort.postMessage({ t: "mem", memory: kbd ? memory : null, writes: kbd ? kbd.writes : null,
                          pending: kbd ? kbd.pending : null });

  fs.mkdirSync(flashDir, { recursive: true });
  FS.mkdir(FLASH);
  const files = installFiles({ FS, flashDir, flashLimit, ramDisk, log });
  files.load();
  files.install();
  FS.mkdir("/vboard");
  for (const [name, text] of Object.entries(vmFiles)) FS.writeFile("/vboard/" + name, text);
  FS.writeFile("/vboard/vboard_config.py", configPy);

  resetRequested = false;
  printError(runCode(SETUP, false));
  // As on a board: boot.py always, main.py only when the friendly REPL is next.
  for (const f of mode === "friendly" ? ["boot.py", "main.py"] : ["boot.py"]) {
    if (FS.analyzePath(FLASH + "/" + f).exists) {
      printError(runCode(`import vboard_rt\nvboard_rt.run_file(${JSON.stringify(f)})`));
      if (resetRequested) return false;
    }
  }
  if (mode === "friendly") {
    mp.replInit();
  } else {
    suppressOutput = true;
    mp.replInit();
    mp.replProcessChar(CTRL_A);
    suppressOutput = false;
    emitRaw(RAW_BANNER);
  }
  return true;
}

let ready = false;
let pumping = false;

async function reboot(soft) {
  ready = false;
  if (soft) emitRaw("MPY: soft reboot\r\n");
  try {
    if (!(await bootVM())) {
      hardReset();
      return;
    }
  } catch (e) {
    log(`VM failed to start: ${e.stack || e}`);
    parentPort.postMessage({ t: "fatal" });
    return;
  }
  ready = true;
  parentPort.postMessage({ t: "ready" });
  pump();
}

// The board's simulated time (vboard.Board.clock_us) goes on across resets: hand it to the
// server, which gives it to the next VM.
function boardClockUs() {
  try {
    const v = mp.pyimport("vboard").board.clock_s();
    return typeof v === "number" && Number.isFinite(v) ? Math.round(v * 1e6) : null;
  } catch {
    return null;
  }
}

function hardReset() {
  ready = false;
  parentPort.postMessage({ t: "hard-reset", clockUs: boardClockUs() });
}

// A soft reset is a new VM in a new worker, started by the server: the old one's memory goes
// with its thread (a VM instance re-created in the same worker is never freed: about 1.2 MB a
// reset).  RAM is lost either way; flash, the serial line and unread input stay.
function softReset() {
  ready = false;
  parentPort.postMessage({ t: "soft-reset", mode, clockUs: boardClockUs() });
}

// ------------------------------------------------------------ REPL

let rawBuf = [];
let pasting = false;
let windowRemain = 0;

function rawExec(src, pasted) {
  if (pasted) emitRaw("\x04"); // end of paste acknowledged
  const err = runCode(Buffer.from(src).toString("utf8"));
  emitRaw("\x04");
  if (err && err.type !== "SystemExit") emitText(err.message);
  emitRaw("\x04");
  if (resetRequested) return hardReset();
  if (err && err.type === "SystemExit") return softReset();
  emitRaw(">");
}

function rawChar(c) {
  if (pasting) {
    if (c === CTRL_D) {
      pasting = false;
      const src = rawBuf;
      rawBuf = [];
      return rawExec(src, true);
    }
    if (c === CTRL_C) {
      // A board's paste reader raises KeyboardInterrupt at this point.
      pasting = false;
      rawBuf = [];
      emitRaw("\x04\x04");
      emitText("KeyboardInterrupt: \n");
      emitRaw("\x04>");
      return;
    }
    rawBuf.push(c);
    if (--windowRemain === 0) {
      windowRemain = PASTE_WINDOW;
      emitRaw("\x01");
    }
    return;
  }
  switch (c) {
    case CTRL_A:
      if (rawBuf.length === 2 && rawBuf[0] === CTRL_E) {
        const cmd = rawBuf[1];
        rawBuf = [];
        if (cmd !== 0x41) return emitRaw("R\x00>");
        pasting = true;
        windowRemain = PASTE_WINDOW;
        return emitRaw("R\x01" + String.fromCharCode(PASTE_WINDOW & 0xff, PASTE_WINDOW >> 8) + "\x01");
      }
      rawBuf = [];
      return emitRaw(RAW_BANNER);
    case CTRL_B:
      rawBuf = [];
      mode = "friendly";
      return vmChar(CTRL_B); // the VM leaves raw mode and prints its banner
    case CTRL_C:
      rawBuf = [];
      return;
    case CTRL_D: {
      emitRaw("OK");
      if (rawBuf.length === 0) {
        emitRaw("\r\n");
        return softReset();
      }
      const src = rawBuf;
      rawBuf = [];
      return rawExec(src, false);
    }
    default:
      rawBuf.push(c);
  }
}

// One character into the VM's own REPL.
function vmChar(c) {
  captured = "";
  clearPendingInterrupt();
  setBusy(true);
  let ret;
  try {
    ret = mp.replProcessChar(c);
  } finally {
    setBusy(false);
  }
  if (pendingInterrupt()) {
    // Ctrl-C landed while the VM was only editing the line: on a board that
    // is an ordinary keypress, so deliver it as one.
    clearPendingInterrupt();
    ret = ret || mp.replProcessChar(CTRL_C);
  }
  if (resetRequested) return hardReset();
  if (ret & PYEXEC_FORCED_EXIT) return softReset();
  if (c === CTRL_A && captured.endsWith(RAW_BANNER)) mode = "raw";
}

function pump() {
  if (pumping) return;
  pumping = true;
  try {
    let pasted = 0;
    while (ready) {
      applyFlush();
      const c = inRing.readByte();
      if (c < 0) break;
      if (mode === "raw") {
        if (pasting) pasted++;
        rawChar(c);
      } else vmChar(c);
    }
    // Raw paste: grant another window as soon as a piece of code has arrived, not only when a
    // window is used up (the protocol allows a \x01 at any time).  mpremote sends a command and
    // its closing Ctrl-D as two small writes; over TCP the second waits (Nagle) for the
    // acknowledgement of the first, which the host delays up to 40 ms unless data goes back.
    // This \x01 is that data: about 15x faster `cp` of many small chunks over socket://.
    if (pasting && pasted) {
      windowRemain += PASTE_WINDOW;
      emitRaw("\x01");
    }
  } catch (e) {
    log(`VM crashed: ${e.stack || e}`);
    emitRaw("\r\n[virtual board: the VM crashed; resetting]\r\n");
    hardReset();
  } finally {
    pumping = false;
  }
}

parentPort.on("message", (m) => {
  if (m.t === "in") pump();
});

reboot(Boolean(workerData.soft));
