// The virtual Pico's sensors: the virtual board's PCB and world (tools/vboard/vm: vboard.py,
// vboard_devices.py, vboard_sensors.py, the register models in tools/sim) run unchanged in a
// MicroPython WebAssembly VM inside this process, and answer the emulated RP2040's I2C, SPI and
// ADC peripherals through pico_bus.py. One world, two boards: no second copy of a model.

import fs from "node:fs";
import path from "node:path";
import { fileURLToPath, pathToFileURL } from "node:url";

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, "..", "..");

export async function loadWorld({ scenario = "steady", profile = "", timeScale = 1, clockUs = 0,
  devices = path.join(REPO, "tools", "vboard", "vm", "vboard_devices.py") } = {}) {
  const wasmDir = process.env.MPY_WASM_DIR ||
    path.join(REPO, "tools", "node_modules", "@micropython", "micropython-webassembly-pyscript");
  const { loadMicroPython } = await import(pathToFileURL(path.join(wasmDir, "micropython.mjs")).href);
  const log = [];
  const mp = await loadMicroPython({
    heapsize: 4 * 1024 * 1024,
    stdout: (s) => log.push(s),
    stderr: (s) => log.push(s),
  });
  mp.FS.mkdir("/world");
  const vm = path.join(REPO, "tools", "vboard", "vm");
  const files = {
    "vboard.py": path.join(vm, "vboard.py"),
    "vboard_sensors.py": path.join(vm, "vboard_sensors.py"),
    "vboard_devices.py": devices,
    "pico_bus.py": path.join(HERE, "pico_bus.py"),
  };
  for (const m of ["mlx90609_sim.py", "mpu6xxx_sim.py", "analog_gyro_sim.py"]) {
    files[m] = path.join(REPO, "tools", "sim", m);
  }
  for (const [name, p] of Object.entries(files)) mp.FS.writeFile("/world/" + name, fs.readFileSync(p));
  // the same settings the virtual board's server gives its VM (tools/vboard/server.mjs, configPy)
  mp.FS.writeFile("/world/vboard_config.py",
    `CLOCK_US = ${Math.max(0, Math.round(clockUs))}\nTIME_SCALE = ${timeScale}\n` +
    `SCENARIO = ${JSON.stringify(scenario)}\nPROFILE = ${JSON.stringify(profile)}\n`);
  mp.runPython("import sys\nsys.path.insert(0, '/world')\nimport pico_bus\n");
  if (log.length) throw new Error(`the world did not start:\n${log.join("\n")}`);
  const pb = mp.pyimport("pico_bus");
  const us = (ns) => ns / 1e9 + 1e-12; // seconds, never an exact integer (the bridge's ints are 32-bit)
  const csPins = String(pb.cs_pins()).split(",").filter(Boolean).map(Number);
  const divider = Number(pb.adc_divider());
  // the bus object rp2040.mjs wires to the peripherals (times in ns of the RP2040's clock)
  return {
    mp,
    i2cPresent: (bus, addr) => Boolean(pb.i2c_present(bus, addr)),
    i2cWrite: (bus, addr, bytes, ns) => pb.i2c_write(bus, addr, Buffer.from(bytes).toString("hex"), us(ns)),
    i2cRead: (bus, addr, n, ns) => Buffer.from(pb.i2c_read(bus, addr, n, us(ns)), "hex"),
    csPins: () => csPins,
    adcDivider: () => divider,
    pinChanged: (pin, level, ns) => pb.pin(pin, level, us(ns)),
    spiExchange: (bus, byte, ns) => pb.spi_exchange(bus, byte, us(ns)),
    adcRead: (ch, ns) => pb.adc(ch, us(ns)),
    reset: (ns) => pb.reset(us(ns)),
    // a world control request (control.mjs, checked there) as JSON text; the answer as JSON text
    control: (req, ns) => String(pb.control(req, us(ns))),
    clockUs: () => Math.round(Number(pb.clock_s()) * 1e6),
  };
}
