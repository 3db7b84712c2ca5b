// Power-on of the virtual Pico: the firmware, the bootrom and the symbols the emulator layer
// needs from build/fw/rp2 (make setup), the world with its parts, and the wiring of
// boards/pico.py (read from that file, so the pins are said once).

import fs from "node:fs";
import path from "node:path";
import { fileURLToPath, pathToFileURL } from "node:url";
import { Pico, elfFunctions, elfSymbols } from "./rp2040.mjs";
import { loadWorld } from "./world.mjs";

const HERE = path.dirname(fileURLToPath(import.meta.url));
export const REPO = path.resolve(HERE, "..", "..");
export const FW_DIR = process.env.PICO_FW_DIR || path.join(REPO, "build", "fw", "rp2");

// boards/pico.py: I2C_SDA = 4 ... (the user-side view of the same PCB)
export function boardPins(file = path.join(REPO, "boards", "pico.py")) {
  const text = fs.readFileSync(file, "utf8");
  const num = (name) => {
    const m = new RegExp(`^${name}\\s*=\\s*(\\d+)`, "m").exec(text);
    if (!m) throw new Error(`${file}: no ${name}`);
    return Number(m[1]);
  };
  const div = /^ADC_DIVIDER\s*=\s*([0-9.]+)/m.exec(text);
  return { i2cId: num("I2C_ID"), sda: num("I2C_SDA"), scl: num("I2C_SCL"), cs: num("MLX_CS"),
    adcDivider: div ? Number(div[1]) : 1.0 };
}

export async function loadFirmware(dir = FW_DIR) {
  const need = ["firmware.bin", "firmware.elf", "bootrom.mjs"].map((f) => path.join(dir, f));
  const gone = need.filter((f) => !fs.existsSync(f));
  if (gone.length) {
    throw new Error(`${gone.map((f) => path.relative(process.cwd(), f)).join(", ")} missing: run make setup`);
  }
  const { bootromB1 } = await import(pathToFileURL(need[2]).href);
  const elf = fs.readFileSync(need[1]);
  const syms = elfSymbols(elf, ["i2c_read_blocking_until", "i2c0_inst", "i2c1_inst"]);
  for (const k of ["i2c_read_blocking_until", "i2c0_inst", "i2c1_inst"]) {
    if (syms[k] === undefined) throw new Error(`${need[1]}: no symbol ${k}`);
  }
  return { firmware: fs.readFileSync(need[0]), bootrom: bootromB1, syms, symbolAt: elfFunctions(elf) };
}

// { pico, world, restart(), resetRequested(), close() }; world: loadWorld's options, or an
// already loaded world (a restart keeps it)
export async function bootPico({ image, world = {}, onSerial = () => {}, log = () => {}, fw = null }) {
  fw = fw || (await loadFirmware());
  const bus = world.i2cRead ? world : await loadWorld(world);
  const pins = boardPins();
  const wired = bus.csPins();
  if (!wired.includes(pins.cs)) {
    throw new Error(`boards/pico.py has the MLX90609's CS on GP${pins.cs}, the world wires it to ${wired}`);
  }
  if (bus.adcDivider() !== pins.adcDivider) {
    throw new Error(`boards/pico.py has ADC_DIVIDER = ${pins.adcDivider}, the world's analog gyro a 1:${bus.adcDivider()} divider`);
  }
  const make = () => {
    const p = new Pico({ firmware: fw.firmware, bootrom: fw.bootrom, image, bus, onSerial, symbolAt: fw.symbolAt });
    p.hookI2cReads(fw.syms.i2c_read_blocking_until, [fw.syms.i2c0_inst, fw.syms.i2c1_inst]);
    p.i2cOnPins(pins.i2cId, pins.sda, pins.scl);
    return p;
  };
  const board = {
    pico: make(),
    world: bus,
    fw,
    resetRequested: () => board.pico.resetRequested,
    restart() {
      // the MCU restarts; the parts and their world go on
      board.pico.close();
      bus.reset(0);
      board.pico = make();
      log("machine.reset(): the RP2040 restarted");
    },
    close() {
      board.pico.close();
    },
  };
  return board;
}
