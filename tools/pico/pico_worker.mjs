// The virtual Pico's CPU thread behind the virtual board's front end (tools/vboard/server.mjs
// --board pico): the real RP2040 firmware on rp2040js (rp2040.mjs) with the simulated parts
// (world.mjs), its USB CDC serial line carried by the same byte rings as the VM board's.
//
// Ctrl-C, Ctrl-D, the raw REPL and raw paste are the firmware's own: bytes go through as they
// would over USB. machine.reset() (the watchdog) restarts the RP2040 from the flash image; the
// sensors and their world keep going, as a board's parts do over an MCU reset.
//
// Time: the RP2040's simulated clock. Code runs as fast as the emulator can (about a fifth of
// real time); while the core sleeps (WFI/WFE: the REPL waiting, time.sleep) the clock is held to
// the wall clock, so a sleep takes its real time and the world does not race ahead while you
// type. PICO_REALTIME=0 lets sleeps pass at once instead.

import { parentPort, receiveMessageOnPort, workerData } from "node:worker_threads";
import { CTL, Ring } from "../vboard/rings.mjs";
import { bootPico } from "./boot.mjs";

const { shared, image, world: worldOpts, realtime, control } = workerData;
const ctl = new Int32Array(shared.ctl);
const inRing = new Ring(ctl, shared.inBuf, CTL.IN_W, CTL.IN_R);
const outRing = new Ring(ctl, shared.outBuf, CTL.OUT_W, CTL.OUT_R);

function log(msg) {
  parentPort.postMessage({ t: "log", msg });
}

function notifyOut() {
  if (Atomics.compareExchange(ctl, CTL.OUT_NOTIFY, 0, 1) === 0) parentPort.postMessage({ t: "out" });
}

function emit(bytes) {
  let i = 0;
  while (i < bytes.length) {
    i += outRing.write(bytes, i);
    notifyOut();
    if (i < bytes.length) Atomics.wait(ctl, CTL.OUT_R, Atomics.load(ctl, CTL.OUT_R), 50);
  }
}

let board;
try {
  board = await bootPico({ image, world: worldOpts, onSerial: emit, log });
} catch (e) {
  log(`the Pico did not start: ${e.stack || e}`);
  parentPort.postMessage({ t: "fatal" });
  throw e;
}

const SLICE_NS = 2e6; // 2 ms of RP2040 time between looks at the serial line
const MAX_LAG_NS = 50e6;
let wall0 = performance.now();
let sim0 = board.pico.nanos;

// world control requests (tools/pico/control.mjs), each at the RP2040's time between two slices
function worldRequests() {
  let m;
  while (control && (m = receiveMessageOnPort(control))) {
    const { id, req } = m.message;
    let answer;
    try {
      answer = JSON.parse(board.world.control(JSON.stringify(req), board.pico.nanos));
    } catch (e) {
      answer = { ok: false, error: String(e.message || e) };
    }
    control.postMessage({ id, answer });
  }
}

function loop() {
  for (;;) {
    worldRequests();
    const input = inRing.read(4096);
    if (input.length) board.pico.serialIn(input);
    const pico = board.pico;
    let limit = pico.nanos + SLICE_NS;
    if (realtime) {
      const wallNs = sim0 + (performance.now() - wall0) * 1e6;
      if (wallNs - pico.nanos > MAX_LAG_NS) {
        // busy code runs slower than real time: do not let the next sleep catch up at once
        sim0 = pico.nanos;
        wall0 = performance.now();
      }
      limit = Math.min(limit, Math.max(wallNs, pico.nanos) + SLICE_NS);
    }
    const idle = pico.run(limit);
    if (board.resetRequested()) {
      board.restart();
      sim0 = board.pico.nanos;
      wall0 = performance.now();
      continue;
    }
    if (pico.powerLost) {
      log("power cut: the RP2040 stopped");
      return;
    }
    if (idle || (realtime && pico.mcu.core.waiting)) {
      // nothing to do before the next alarm or the wall clock: wait for input (or 1 ms)
      Atomics.wait(ctl, CTL.IN_W, Atomics.load(ctl, CTL.IN_W), 1);
    }
  }
}

parentPort.on("message", () => {});
try {
  loop();
} catch (e) {
  log(`the emulated RP2040 failed: ${e.stack || e}`);
  parentPort.postMessage({ t: "fatal" });
} finally {
  board.close(); // the image stays as the flash left it
}
