// Power cuts through a script's flash writes on the virtual Pico, each followed by a reboot.
//
//   node tools/pico/cut.mjs SPEC.json      (tools/board/picoctl.py, cut_sweep)
//
// SPEC: {image, setup, action, check, cuts: [{op, frac} | {cycle}]}. The image is copied, never
// changed. One power-on runs `setup` and powers off cleanly: the base image. A reference power-on
// runs `action` on the base and records its flash operations (erase / program, when, where).
// Then for each cut: the base again, `action` with the power cut at the k-th flash operation,
// fraction f of its time (that operation left half done: rp2040.mjs, flashOp) or n cycles after
// the action was handed to the REPL; a new power-on runs `check`. Everything runs on the real
// firmware's raw REPL over USB CDC. The simulated parts are loaded once and kept over the cuts (a
// store's save does not touch them). Prints JSON: the reference and each cut's result.

import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { bootPico, loadFirmware } from "./boot.mjs";
import { CYCLE_NS } from "./rp2040.mjs";
import { loadWorld } from "./world.mjs";

const spec = JSON.parse(fs.readFileSync(process.argv[2], "utf8"));
const fw = await loadFirmware();
const world = await loadWorld({});
const tmp = fs.mkdtempSync(path.join(os.tmpdir(), "tempcomp-cut-"));

class Repl {
  constructor(board) {
    this.board = board;
    this.out = "";
  }

  // run the RP2040 until pred(output) holds (or the power goes); limit in simulated seconds
  until(pred, what, limitS = 120) {
    const p = this.board.pico;
    const end = p.nanos + limitS * 1e9;
    while (!pred(this.out)) {
      if (p.powerLost) return false;
      if (p.nanos > end) throw new Error(`no ${what} within ${limitS} s of RP2040 time; output:\n${this.out.slice(-2000)}`);
      p.run(p.nanos + 1e6);
    }
    return true;
  }

  send(s) {
    this.board.pico.serialIn(Buffer.from(s, "latin1"));
  }

  enterRaw() {
    this.until(() => this.board.pico.usbConnected, "USB connection", 30);
    this.send("\r\x03\x03\x01");
    this.until((o) => o.endsWith("raw REPL; CTRL-B to exit\r\n>"), "raw REPL", 30);
    this.out = "";
  }

  // raw REPL exec; returns {out, err} or null when the power went first
  exec(code, limitS = 300) {
    this.out = "";
    this.send(Buffer.from(code, "utf8").toString("latin1") + "\x04");
    if (!this.until((o) => /^OK[\s\S]*\x04[\s\S]*\x04>$/.test(o), "end of the script", limitS)) return null;
    const [out, err] = this.out.slice(2, -1).split("\x04");
    this.out = "";
    return { out: out.replace(/\r\n/g, "\n"), err: err.replace(/\r\n/g, "\n") };
  }
}

async function powerOn(image) {
  let repl = null;
  const board = await bootPico({
    image,
    fw,
    world,
    onSerial: (d) => {
      repl.out += Buffer.from(d).toString("latin1");
    },
  });
  repl = new Repl(board);
  repl.enterRaw();
  return repl;
}

function need(r, what) {
  if (!r) throw new Error(`${what}: the power went without a cut`);
  if (r.err) throw new Error(`${what} raised:\n${r.out}\n${r.err}`);
  return r.out;
}

const base = path.join(tmp, "base.img");
fs.copyFileSync(spec.image, base);
let repl = await powerOn(base);
const setupOut = need(repl.exec(spec.setup || "pass"), "setup");
repl.board.close();

// the reference: the action without a cut
fs.copyFileSync(base, path.join(tmp, "ref.img"));
repl = await powerOn(path.join(tmp, "ref.img"));
let p = repl.board.pico;
const op0 = p.flashOps;
const c0 = p.cycles;
p.flashLog = [];
const actionOut = need(repl.exec(spec.action), "action");
const ops = p.flashLog.map((o) => ({
  op: o.op, addr: o.addr, len: o.len,
  start: Math.round(o.t0 / CYCLE_NS) - c0, end: Math.round(o.t1 / CYCLE_NS) - c0,
}));
const actionCycles = p.cycles - c0;
repl.board.close();
fs.copyFileSync(path.join(tmp, "ref.img"), path.join(tmp, "after.img"));
repl = await powerOn(path.join(tmp, "after.img"));
const refCheck = need(repl.exec(spec.check), "check after the uncut action");
repl.board.close();

const results = [];
for (const cut of spec.cuts) {
  const img = path.join(tmp, "cut.img");
  fs.copyFileSync(base, img);
  repl = await powerOn(img);
  p = repl.board.pico;
  p.flashLog = [];
  const opBase = p.flashOps;
  const start = p.cycles;
  p.cut = cut.cycle !== undefined ? { cycle: start + cut.cycle } : { op: opBase + cut.op, frac: cut.frac };
  const r = repl.exec(spec.action);
  const fell = p.flashLog.find((o) => o.done < o.len);
  repl.board.close();
  const res = { cut, powered_off: p.powerLost, at_cycle: p.cycles - start,
    ops_done: p.flashLog.filter((o) => o.done === o.len).length,
    torn: fell ? { op: fell.op, addr: fell.addr, len: fell.len, done: fell.done } : null,
    action_finished: r !== null };
  repl = await powerOn(img);
  const c = repl.exec(spec.check);
  repl.board.close();
  res.check = c ? c.out : null;
  res.check_err = c ? c.err : "the power went during the check";
  results.push(res);
}

fs.rmSync(tmp, { recursive: true, force: true });
process.stdout.write(JSON.stringify({
  setup: setupOut, action: actionOut, reference: { ops, cycles: actionCycles, check: refCheck, first_op: op0 },
  cuts: results,
}) + "\n");
process.exit(0);
