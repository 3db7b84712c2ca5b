// The virtual Raspberry Pi Pico: the real MicroPython rp2 firmware (build/fw/rp2) on rp2040js's
// emulated RP2040, with the few pieces rp2040js 1.4.1 leaves out (../shared/vendor/README.md):
//
// - flash writes: the bootrom's flash_range_erase / flash_range_program (found through its
//   function table) are replaced by breakpoints answered here, on mcu.flash, with a NOR part's
//   semantics (erase to 0xFF, program ANDs) and its typical timings; every change is written
//   through to a host image of the filesystem region, so littlefs persists between runs;
// - a power cut at a chosen cycle (absolute, or inside the k-th flash operation): the operation
//   is left half done (the erased or programmed prefix up to that cycle) and the CPU stops;
// - the UART TX interrupt, raised once per byte written instead of on every register access;
// - USB CDC: the host's OUT transfers wait for data instead of polling with empty packets;
// - the I2C address phase at the GPIO level (the rp2 port's I2C.scan() bit-bangs the pins).
//
// The sensors answer the real I2C, SPI and ADC peripherals through a `bus` object (world.mjs).
// Time is the RP2040's: 125 MHz, 8 ns a cycle; run() executes until a simulated deadline.

import fs from "node:fs";
import { Simulator, USBCDC, GPIOPinState, ConsoleLogger, LogLevel } from "rp2040js";

export const CYCLE_NS = 8; // 125 MHz
export const FLASH_SIZE = 2 * 1024 * 1024; // RPI_PICO: W25Q16JV, 2 MiB
export const FS_BYTES = 1408 * 1024; // ports/rp2 MICROPY_HW_FLASH_STORAGE_BYTES
export const FS_BASE = FLASH_SIZE - FS_BYTES;
const XIP_BASE = 0x10000000;

// W25Q16JV typical times (datasheet 9.6: tSE 45 ms per 4 KB sector, tBE2 150 ms per 64 KB block,
// tPP 0.4 ms per 256-byte page) plus the bytes' time on the SPI link (the ROM's program loop
// clocks the page out serially)
const SECTOR = 4096;
const BLOCK = 65536;
const PAGE = 256;
const T_SECTOR_NS = 45e6;
const T_BLOCK_NS = 150e6;
const T_PAGE_NS = 0.4e6;
const BYTE_LINK_NS = 8 * 16; // 8 bits at clk_sys / 2 (62.5 MHz)

const BK_ERASE = 0xe1;
const BK_PROGRAM = 0xe2;

// rp2040js's CortexM0Core takes the bootrom as 32-bit words; the function table is reached
// through the 16-bit pointer at 0x14 (RP2040 datasheet 2.8.3): (code, address) pairs of u16
function romFunction(rom, code) {
  const u16 = new Uint16Array(rom.buffer, rom.byteOffset, rom.length * 2);
  let p = u16[0x14 / 2];
  for (let i = 0; i < 256; i++, p += 4) {
    const c = u16[p / 2];
    if (c === 0) break;
    if (c === code) return u16[p / 2 + 1] & ~1;
  }
  throw new Error(`bootrom: no function ${String.fromCharCode(code & 0xff, code >> 8)}`);
}

function patchedBootrom(rom) {
  const out = Uint32Array.from(rom);
  const u16 = new Uint16Array(out.buffer);
  const code = (s) => s.charCodeAt(0) | (s.charCodeAt(1) << 8);
  u16[romFunction(out, code("RE")) / 2] = 0xbe00 | BK_ERASE; // BKPT: flash_range_erase
  u16[romFunction(out, code("RP")) / 2] = 0xbe00 | BK_PROGRAM; // BKPT: flash_range_program
  return out;
}

class Quiet extends ConsoleLogger {
  // rp2040js reports unimplemented registers the firmware touches at boot; keep errors only
  constructor() {
    super(LogLevel.Error, false);
  }
}

export class Pico {
  // firmware: Uint8Array of firmware.bin; bootrom: the B1 mask ROM words; image: path of the host
  // file holding the filesystem region (created erased), or null for a flash that is not kept
  // symbolAt(addr): the firmware function holding addr (elfFunctions), for fault messages
  constructor({ firmware, bootrom, image = null, bus = null, onSerial = () => {}, onUart = null, symbolAt = null }) {
    this.symbolAt = symbolAt;
    this.sim = new Simulator();
    const mcu = (this.mcu = this.sim.rp2040);
    mcu.logger = new Quiet();
    mcu.loadBootrom(patchedBootrom(bootrom));
    mcu.flash.fill(0xff, 0, FLASH_SIZE);
    mcu.flash.set(firmware, 0);
    this.image = image;
    this.imageFd = null;
    if (image) this.loadImage(image);
    this.flashOps = 0; // erase / program operations since power-on
    this.flashLog = null; // [{op, addr, len, t0, t1}] when recording
    this.cut = null; // {cycle} or {op, frac}: where the power goes
    this.powerLost = false;
    this.resetRequested = false;
    this.bus = bus;
    mcu.onBreak = (code) => this.onBreak(code);
    this.setupUsb(onSerial);
    this.setupUart(onUart);
    this.setupWatchdog();
    if (bus) this.wireBus(bus);
    mcu.core.PC = XIP_BASE; // boot2 at the start of flash, then the firmware's crt0
  }

  get cycles() {
    return Math.round(this.mcu.clock.nanos / CYCLE_NS);
  }

  get nanos() {
    return this.mcu.clock.nanos;
  }

  // ------------------------------------------------------------ flash

  loadImage(path) {
    // never through a link: a name in build/pico replaced by a symlink (to ~/.bashrc, say)
    // must not have the flash written into its target (as the VM board's flash directory)
    const C = fs.constants;
    let fd;
    try {
      fd = fs.openSync(path, C.O_RDWR | C.O_NOFOLLOW);
    } catch (e) {
      if (e.code === "ELOOP") throw new Error(`${path} is a symbolic link: the flash image is not written through links`);
      if (e.code !== "ENOENT") throw e;
      fd = fs.openSync(path, C.O_RDWR | C.O_CREAT | C.O_EXCL | C.O_NOFOLLOW, 0o600);
    }
    if (!fs.fstatSync(fd).isFile()) {
      fs.closeSync(fd);
      throw new Error(`${path} is not a regular file: not a flash image`);
    }
    const size = fs.fstatSync(fd).size;
    if (size !== FS_BYTES) {
      if (size !== 0) throw new Error(`${path}: ${size} bytes, not a ${FS_BYTES}-byte filesystem image`);
      const erased = Buffer.alloc(FS_BYTES, 0xff);
      fs.writeSync(fd, erased, 0, FS_BYTES, 0);
    }
    const data = Buffer.alloc(FS_BYTES);
    fs.readSync(fd, data, 0, FS_BYTES, 0);
    this.mcu.flash.set(data, FS_BASE);
    this.imageFd = fd;
  }

  closeImage() {
    if (this.imageFd !== null) fs.closeSync(this.imageFd);
    this.imageFd = null;
  }

  // what changed in mcu.flash goes to the host image at once (a killed process loses nothing
  // the firmware was told is written)
  persist(addr, len) {
    if (this.imageFd === null) return;
    const lo = Math.max(addr, FS_BASE);
    const hi = Math.min(addr + len, FLASH_SIZE);
    if (hi <= lo) return;
    fs.writeSync(this.imageFd, this.mcu.flash, lo, hi - lo, lo - FS_BASE);
  }

  onBreak(code) {
    const core = this.mcu.core;
    const r = core.registers;
    if (code === BK_ERASE) {
      this.flashOp("erase", r[0], r[1], r[2], 0);
    } else if (code === BK_PROGRAM) {
      this.flashOp("program", r[0], r[2], 0, r[1]);
    } else {
      // the firmware's own BKPT: pico-sdk's panic() and MicroPython's nlr_jump_fail() (a fatal
      // error: "FATAL: uncaught exception" on the console). Without a debugger a real RP2040
      // takes a HardFault there and halts until a reset; here the CPU stops with that message
      const at = core.PC - 2;
      const fn = this.symbolAt ? this.symbolAt(at) : null;
      throw new Error(`breakpoint ${code} at 0x${at.toString(16)}${fn ? ` in ${fn}` : ""}: the firmware stopped ` +
        "(a real RP2040 halts here until reset)");
    }
    core.PC = core.LR & ~1; // return from the ROM function
  }

  // flash_range_erase(addr, count, block_size, block_cmd) / flash_range_program(addr, data, count)
  flashOp(op, addr, len, blockSize, src) {
    const flash = this.mcu.flash;
    if (addr % (op === "erase" ? SECTOR : PAGE) || len % (op === "erase" ? SECTOR : PAGE) || addr + len > FLASH_SIZE) {
      throw new Error(`flash ${op} 0x${addr.toString(16)}+${len}: not aligned or past the end`);
    }
    // the ROM erases 64 KB blocks where the range allows and block_size says so, sectors elsewhere
    let dur = 0;
    if (op === "erase") {
      let a = addr;
      while (a < addr + len) {
        if (blockSize === BLOCK && a % BLOCK === 0 && addr + len - a >= BLOCK) {
          dur += T_BLOCK_NS;
          a += BLOCK;
        } else {
          dur += T_SECTOR_NS;
          a += SECTOR;
        }
      }
    } else {
      dur = (len / PAGE) * T_PAGE_NS + len * BYTE_LINK_NS;
    }
    const index = this.flashOps++;
    const t0 = this.mcu.clock.nanos;
    // how much is done when the power goes: a prefix of the range, in proportion to the time
    let frac = 1;
    const cut = this.cut;
    if (cut && cut.op === index) frac = cut.frac;
    else if (cut && cut.cycle !== undefined && cut.cycle * CYCLE_NS < t0 + dur) {
      frac = Math.max(0, (cut.cycle * CYCLE_NS - t0) / dur);
    }
    const n = frac >= 1 ? len : Math.floor(len * frac);
    if (op === "erase") {
      flash.fill(0xff, addr, addr + n);
    } else {
      const ram = this.mcu.sram;
      const from = src - 0x20000000;
      if (from < 0 || from + len > ram.length) throw new Error(`flash program from 0x${src.toString(16)}: not in SRAM`);
      for (let i = 0; i < n; i++) flash[addr + i] &= ram[from + i]; // NOR: programming clears bits
    }
    this.persist(addr, n);
    if (this.flashLog) this.flashLog.push({ op, addr, len, t0, t1: t0 + dur, done: n });
    if (frac < 1) {
      this.mcu.clock.tick(dur * frac);
      this.powerCut();
      return;
    }
    // the CPU waits on the flash's busy bit with interrupts off (pico-sdk runs this from RAM)
    this.mcu.clock.tick(dur);
  }

  powerCut() {
    this.powerLost = true;
    this.sim.stop();
  }

  // ------------------------------------------------------------ USB CDC (the REPL)

  setupUsb(onSerial) {
    const cdc = (this.cdc = new USBCDC(this.mcu.usbCtrl));
    this.hostBacklog = [];
    this.usbConnected = false;
    cdc.onDeviceConnected = () => {
      this.usbConnected = true;
      this.pumpHost();
    };
    cdc.onSerialData = (data) => onSerial(data);
    // A host sends an OUT packet only when it has data: park the device's read until then
    // (rp2040js answers at once with an empty packet, which keeps the CPU polling)
    const usb = this.mcu.usbCtrl;
    const orig = usb.onEndpointRead;
    this.pendingRead = null;
    usb.onEndpointRead = (endpoint, size) => {
      if (cdc.txFIFO.itemCount === 0 && this.hostBacklog.length === 0 && endpoint !== 0) {
        this.pendingRead = [endpoint, size];
        return;
      }
      this.pumpHost();
      orig(endpoint, size);
    };
    this.origEndpointRead = orig;
  }

  // bytes from the host (the serial terminal / mpremote) to the firmware
  serialIn(bytes) {
    for (const b of bytes) this.hostBacklog.push(b);
    this.pumpHost();
  }

  pumpHost() {
    const fifo = this.cdc.txFIFO;
    let i = 0;
    while (i < this.hostBacklog.length && !fifo.full) fifo.push(this.hostBacklog[i++]);
    if (i) this.hostBacklog.splice(0, i);
    if (this.pendingRead && fifo.itemCount) {
      const [ep, size] = this.pendingRead;
      this.pendingRead = null;
      this.origEndpointRead(ep, size);
    }
  }

  // ------------------------------------------------------------ UART, watchdog

  setupUart(onUart) {
    for (const [i, uart] of this.mcu.uart.entries()) {
      // rp2040js re-raises UARTTXINTR on every interrupt check, so an enabled TX interrupt never
      // ends (UART.write hangs): raise it once per byte handed to the line instead
      const TXINTR = 1 << 5;
      uart.interruptStatus &= ~TXINTR;
      uart.checkInterrupts = function () {
        this.rp2040.setInterrupt(this.irq, !!(this.interruptStatus & this.interruptMask));
      };
      uart.onByte = (b) => {
        if (onUart) onUart(i, b);
        uart.interruptStatus |= TXINTR;
        uart.checkInterrupts();
      };
    }
  }

  uartIn(i, bytes) {
    for (const b of bytes) this.mcu.uart[i].feedByte(b);
  }

  setupWatchdog() {
    // machine.reset() reboots through the watchdog
    const wd = this.mcu.findPeripheral(0x40058000);
    wd.onWatchdogTrigger = () => {
      this.resetRequested = true;
      this.sim.stop();
    };
  }

  // ------------------------------------------------------------ sensors

  wireBus(bus) {
    const mcu = this.mcu;
    const now = () => mcu.clock.nanos;
    // I2C: byte-level callbacks of the real peripheral; each byte takes its time on the wire
    // (9 SCL periods as the firmware programmed them), which rp2040js leaves at zero
    const i2cTimer = (i2c, fn) => {
      const alarm = mcu.clock.createAlarm(() => {
        const f = alarm.fn;
        alarm.fn = null;
        f();
      });
      return (bits, f) => {
        const period = ((i2c.sclHighPeriod + i2c.sclLowPeriod) * 1e9) / (mcu.clkSys || 125e6);
        alarm.fn = f;
        alarm.schedule(bits * period);
      };
    };
    for (const [n, i2c] of mcu.i2c.entries()) {
      const after = i2cTimer(i2c);
      let addr = -1;
      let wbuf = [];
      let rbuf = null;
      let rpos = 0;
      let reading = false;
      const flush = () => {
        if (addr >= 0 && !reading && wbuf.length) bus.i2cWrite(n, addr, wbuf, now());
        wbuf = [];
        rbuf = null;
      };
      i2c.onStart = (repeated) => {
        if (repeated) flush();
        after(1, () => i2c.completeStart());
      };
      i2c.onConnect = (a, mode) => {
        addr = a;
        reading = mode === 1;
        const ack = bus.i2cPresent(n, a);
        if (ack && reading) {
          // the length of the read the firmware started (i2c_read_blocking_until's count)
          const len = this.i2cReadLen[n] > 0 ? this.i2cReadLen[n] : 1;
          rbuf = bus.i2cRead(n, a, len, now());
          rpos = 0;
        }
        after(9, () => i2c.completeConnect(ack));
      };
      i2c.onWriteByte = (b) => {
        wbuf.push(b);
        after(9, () => i2c.completeWrite(true));
      };
      i2c.onReadByte = () => {
        const v = rbuf && rpos < rbuf.length ? rbuf[rpos++] : 0xff;
        after(9, () => i2c.completeRead(v));
      };
      i2c.onStop = () => {
        flush();
        addr = -1;
        this.i2cReadLen[n] = 0;
        after(1, () => i2c.completeStop());
      };
    }
    this.i2cReadLen = [0, 0];
    // SPI: full duplex, one byte per onTransmit, 8 bit times at the programmed clock
    for (const [n, spi] of mcu.spi.entries()) {
      const alarm = mcu.clock.createAlarm(() => spi.completeTransmit(alarm.value));
      spi.onTransmit = (v) => {
        alarm.value = bus.spiExchange(n, v, now());
        const hz = spi.clockFrequency || 1e6;
        alarm.schedule((spi.dataBits * 1e9) / hz);
      };
    }
    // chip selects and the pins the bus watches (GPIO listeners)
    for (const pin of bus.csPins()) {
      mcu.gpio[pin].addListener((state) => {
        bus.pinChanged(pin, state === GPIOPinState.Low ? 0 : 1, now());
      });
    }
    // ADC: the channel's 16-bit pin level, quantised to the RP2040's 12 bits
    const adc = mcu.adc;
    const adcAlarm = mcu.clock.createAlarm(() => adc.completeADCRead(adcAlarm.value, false));
    adc.onADCRead = (ch) => {
      adcAlarm.value = Math.min(4095, bus.adcRead(ch, now()) >> 4); if (process.env.PICO_DEBUG) console.error("adc", ch, adcAlarm.value);
      adcAlarm.schedule(adc.sampleTime * 1000);
    };
  }

  // The same parts at the GPIO level, for code that bit-bangs the pins: the rp2 port's
  // I2C.scan() (zero-length writes) and SoftI2C writes. Open drain with the board's pull-ups: a
  // line is low while the master or the part pulls it. The part ACKs its address and every byte
  // written (handed over as one transaction at STOP); reads at this level get the released
  // line (0xFF).
  i2cOnPins(n, sdaPin, sclPin) {
    const bus = this.bus;
    const mcu = this.mcu;
    const sdaIo = mcu.gpio[sdaPin];
    const sclIo = mcu.gpio[sclPin];
    const line = (io) => (io.value === GPIOPinState.Low ? 0 : 1);
    let mSda = 1, mScl = 1, dSda = 1;
    let sda = 1, scl = 1;
    let phase = "idle"; // idle, addr, write, read
    let bits = 0, byte = 0, addr = -1, data = [];
    const flush = () => {
      if (phase === "write" && data.length) bus.i2cWrite(n, addr, data, mcu.clock.nanos);
      data = [];
    };
    const update = () => {
      const nSda = mSda & dSda;
      const nScl = mScl;
      if (nScl && scl && nSda !== sda) {
        if (!nSda) {
          flush(); // START (or a repeated one)
          phase = "addr";
          bits = 0;
          byte = 0;
        } else {
          flush(); // STOP
          phase = "idle";
          dSda = 1;
        }
      } else if (nScl && !scl) {
        if (bits < 8 && (phase === "addr" || phase === "write")) {
          byte = (byte << 1) | nSda;
          bits++;
        }
      } else if (!nScl && scl) {
        if (bits === 8) {
          let ack = false;
          if (phase === "addr") {
            addr = byte >> 1;
            ack = bus.i2cPresent(n, addr);
          } else if (phase === "write") {
            data.push(byte);
            ack = true;
          }
          if (ack) dSda = 0;
          else if (phase === "addr") phase = "idle";
          bits = 9;
        } else if (bits === 9) {
          dSda = 1;
          if (phase === "addr") phase = byte & 1 ? "read" : "write";
          bits = 0;
          byte = 0;
        }
      }
      sda = mSda & dSda;
      scl = nScl;
      sdaIo.setInputValue(Boolean(sda));
      sclIo.setInputValue(Boolean(scl));
    };
    sdaIo.addListener(() => {
      mSda = line(sdaIo);
      update();
    });
    sclIo.addListener(() => {
      mScl = line(sclIo);
      update();
    });
    sdaIo.setInputValue(true);
    sclIo.setInputValue(true);
  }

  // the firmware's I2C reads say how many bytes they want only one at a time; the simulated
  // parts answer whole transactions (vboard.py's interface), so the count is taken from the
  // call into pico-sdk's i2c_read_blocking_until(i2c, addr, dst, len, nostop, until)
  hookI2cReads(readFn, i2cBases) {
    const core = this.mcu.core;
    core.blTaken = (c) => {
      if (c.PC === readFn) {
        const n = i2cBases.indexOf(c.registers[0]);
        if (n >= 0) this.i2cReadLen[n] = c.registers[3];
      }
    };
  }

  // ------------------------------------------------------------ running

  // Execute until the simulated clock reaches `untilNs`, the power is cut, a reset is asked for,
  // or stop() is called; returns early (true) when the core sleeps with nothing scheduled.
  run(untilNs) {
    const { mcu, sim } = this;
    const core = mcu.core;
    const clock = mcu.clock;
    sim.stopped = false;
    const cutNs = this.cut && this.cut.cycle !== undefined ? this.cut.cycle * CYCLE_NS : Infinity;
    const limit = Math.min(untilNs, cutNs);
    while (!sim.stopped && clock.nanos < limit) {
      if (core.waiting) {
        const dt = clock.nanosToNextAlarm;
        if (dt <= 0) return true;
        clock.tick(Math.min(dt, limit - clock.nanos));
      } else {
        clock.tick(core.executeInstruction() * CYCLE_NS);
      }
    }
    if (!sim.stopped && clock.nanos >= cutNs) this.powerCut();
    return false;
  }

  stop() {
    this.sim.stop();
  }

  close() {
    this.sim.stop();
    this.closeImage();
  }
}

// The ELF32 symbol table's functions: a lookup address -> "name" (the function whose range holds it)
export function elfFunctions(buf) {
  const dv = new DataView(buf.buffer, buf.byteOffset, buf.byteLength);
  const shoff = dv.getUint32(32, true);
  const shentsize = dv.getUint16(46, true);
  const shnum = dv.getUint16(48, true);
  const fns = [];
  for (let i = 0; i < shnum; i++) {
    const sh = shoff + i * shentsize;
    if (dv.getUint32(sh + 4, true) !== 2) continue; // SHT_SYMTAB
    const off = dv.getUint32(sh + 16, true);
    const size = dv.getUint32(sh + 20, true);
    const strOff = dv.getUint32(shoff + dv.getUint32(sh + 24, true) * shentsize + 16, true);
    for (let p = off; p < off + size; p += 16) {
      if ((buf[p + 12] & 0xf) !== 2) continue; // STT_FUNC
      let s = strOff + dv.getUint32(p, true);
      let name = "";
      while (buf[s]) name += String.fromCharCode(buf[s++]);
      fns.push([dv.getUint32(p + 4, true) & ~1, dv.getUint32(p + 8, true), name]);
    }
  }
  return (addr) => {
    const f = fns.find(([a, n]) => addr >= a && addr < a + Math.max(n, 2));
    return f ? f[2] : null;
  };
}

// An ELF32 symbol table: name -> address (function symbols without the Thumb bit)
export function elfSymbols(buf, wanted) {
  const dv = new DataView(buf.buffer, buf.byteOffset, buf.byteLength);
  if (dv.getUint32(0, false) !== 0x7f454c46) throw new Error("not an ELF file");
  const shoff = dv.getUint32(32, true);
  const shentsize = dv.getUint16(46, true);
  const shnum = dv.getUint16(48, true);
  const out = {};
  for (let i = 0; i < shnum; i++) {
    const sh = shoff + i * shentsize;
    if (dv.getUint32(sh + 4, true) !== 2) continue; // SHT_SYMTAB
    const off = dv.getUint32(sh + 16, true);
    const size = dv.getUint32(sh + 20, true);
    const strSec = shoff + dv.getUint32(sh + 24, true) * shentsize;
    const strOff = dv.getUint32(strSec + 16, true);
    for (let p = off; p < off + size; p += 16) {
      let s = strOff + dv.getUint32(p, true);
      let name = "";
      while (buf[s]) name += String.fromCharCode(buf[s++]);
      if (wanted.includes(name)) out[name] = dv.getUint32(p + 4, true) & ~1;
    }
  }
  return out;
}
