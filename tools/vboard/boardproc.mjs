// A board process on the host: its pid file, its --detach start and log, and `--stop`, which
// kills the process a pid file names only if that process is this board.  Shared by the board
// front ends (server.mjs; the RP2040 board reuses them).
//
// Both files live in a directory the user owns (build/vboard/ by default), but a name in it may
// have been replaced by a symlink (to ~/.bashrc, say): they are created as new files under a
// fresh name (O_CREAT | O_EXCL | O_NOFOLLOW) and renamed over the name, which replaces a link
// instead of writing through it, and read with O_NOFOLLOW.

import fs from "node:fs";
import path from "node:path";
import { execFileSync, spawn } from "node:child_process";

const C = fs.constants;
const HAVE_PROC = fs.existsSync("/proc/self/stat");

// A new regular file at `file`, open for writing (flags: C.O_WRONLY or C.O_RDWR); returns its fd.
export function createFile(file, { mode = 0o644, flags = C.O_WRONLY } = {}) {
  const dir = path.dirname(file);
  for (let i = 0; ; i++) {
    const tmp = path.join(dir, `.${path.basename(file)}.new-${process.pid}-${i}`);
    let fd;
    try {
      fd = fs.openSync(tmp, flags | C.O_CREAT | C.O_EXCL | C.O_NOFOLLOW, mode);
    } catch (e) {
      if (e.code === "EEXIST" && i < 100) continue;
      throw e;
    }
    try {
      fs.renameSync(tmp, file);
    } catch (e) {
      fs.closeSync(fd);
      fs.rmSync(tmp, { force: true });
      throw e;
    }
    return fd;
  }
}

// The text of a small regular file, or null if `file` is missing, a link, a FIFO, a device,
// or bigger than `max` bytes.
export function readSmallFile(file, max = 4096) {
  let fd;
  try {
    fd = fs.openSync(file, C.O_RDONLY | C.O_NOFOLLOW | C.O_NONBLOCK);
  } catch {
    return null;
  }
  try {
    const st = fs.fstatSync(fd);
    if (!st.isFile() || st.size > max) return null;
    const buf = Buffer.alloc(max + 1);
    const n = fs.readSync(fd, buf, 0, max + 1, 0);
    return n > max ? null : buf.subarray(0, n).toString("utf8");
  } finally {
    fs.closeSync(fd);
  }
}

// Who a pid is: its start time (clock ticks since boot on Linux: a later process that reuses the
// pid has another), its command line as it was executed, its executable and working directory.
export function procInfo(pid) {
  if (HAVE_PROC) {
    try {
      const stat = fs.readFileSync(`/proc/${pid}/stat`, "utf8");
      const start = stat.slice(stat.lastIndexOf(")") + 2).split(" ")[19];
      const argv = fs.readFileSync(`/proc/${pid}/cmdline`, "utf8").split("\0");
      if (argv.length && argv[argv.length - 1] === "") argv.pop();
      const link = (what) => {
        try {
          return fs.readlinkSync(`/proc/${pid}/${what}`);
        } catch {
          return null; // another user's process
        }
      };
      return { start, argv, exe: link("exe"), cwd: link("cwd") };
    } catch {
      return null;
    }
  }
  try {
    // no /proc (macOS): ps gives the start time and the command as one string
    const out = execFileSync("ps", ["-o", "lstart=,command=", "-p", String(pid)], { encoding: "utf8" }).trim();
    if (!out) return null;
    return { start: out.slice(0, 24).trim(), argv: [out.slice(24).trim()], exe: null, cwd: null };
  } catch {
    return null;
  }
}

function realpathOr(p) {
  try {
    return fs.realpathSync(p);
  } catch {
    return null;
  }
}

// The record a board writes at start: enough to recognise exactly this process later.
export function selfRecord(server) {
  const me = procInfo(process.pid);
  return {
    pid: process.pid,
    start: me ? me.start : null,
    node: process.execPath,
    argv: me ? me.argv : [process.execPath, ...process.execArgv, ...process.argv.slice(1)],
    server,
  };
}

export function writePidfile(file, server) {
  fs.mkdirSync(path.dirname(file), { recursive: true });
  const fd = createFile(file);
  try {
    fs.writeSync(fd, JSON.stringify(selfRecord(server)) + "\n");
  } finally {
    fs.closeSync(fd);
  }
}

// The parsed record, {pid: NaN} for a file that is not a pid file, null if there is none.
export function readPidfile(file) {
  if (!fs.existsSync(file) && !isLink(file)) return null;
  const text = readSmallFile(file);
  try {
    const o = JSON.parse(text);
    if (o && Number.isInteger(o.pid) && o.pid > 0) return o;
  } catch {}
  return { pid: NaN };
}

function isLink(file) {
  try {
    return fs.lstatSync(file).isSymbolicLink();
  } catch {
    return false;
  }
}

// Why the process `rec` names is not the board that `server` runs (null: it is): the same
// start time, the same command line as recorded, run by the recorded node binary, with this
// repository's server script among its arguments.
export function notThisBoard(rec, server) {
  if (!Number.isInteger(rec.pid)) return "is not a virtual board's pid file";
  const who = procInfo(rec.pid);
  if (!who) return `names pid ${rec.pid}, which is not running`;
  const shown = `(${who.argv.join(" ").slice(0, 80) || "?"})`;
  if (rec.server !== server) {
    return `was written by another server (${String(rec.server).slice(0, 80)}), not ${server}`;
  }
  if (!rec.start || who.start !== rec.start || !Array.isArray(rec.argv) ||
      rec.argv.length !== who.argv.length || rec.argv.some((a, i) => a !== who.argv[i])) {
    return `names pid ${rec.pid}, which is now another process ${shown}`;
  }
  if (HAVE_PROC) {
    const exe = who.exe && who.exe.replace(/ \(deleted\)$/, "");
    if (!exe || realpathOr(exe) !== realpathOr(rec.node)) {
      return `names pid ${rec.pid}, which does not run the recorded node ${shown}`;
    }
    const me = realpathOr(server);
    if (!who.cwd || !who.argv.slice(1).some((a) => realpathOr(path.resolve(who.cwd, a)) === me)) {
      return `names pid ${rec.pid}, which does not run ${server} ${shown}`;
    }
  } else if (!who.argv[0].includes(server)) {
    return `names pid ${rec.pid}, which does not run ${server} ${shown}`;
  }
  return null;
}

function sleepMs(ms) {
  Atomics.wait(new Int32Array(new SharedArrayBuffer(4)), 0, 0, ms);
}

// `--stop`: SIGTERM to the board the pid file names, if it is this board; returns an exit code.
export function stopByPidfile(file, server, name = "virtual board") {
  const rel = path.relative(process.cwd(), file) || file;
  const rec = readPidfile(file);
  if (!rec) {
    console.log(`${name}: not running (no ${rel})`);
    return 0;
  }
  const why = notThisBoard(rec, server);
  if (why) {
    console.log(`${name}: not running: ${rel} ${why}; nothing killed, stale pid file removed`);
    fs.rmSync(file, { force: true });
    return 0;
  }
  const pid = rec.pid;
  try {
    process.kill(pid, "SIGTERM");
  } catch {
    console.log(`${name}: pid ${pid} was not running; removing stale pid file`);
    fs.rmSync(file, { force: true });
    return 0;
  }
  const deadline = Date.now() + 5000;
  while (Date.now() < deadline) {
    try {
      process.kill(pid, 0);
      // exited, not yet reaped by its parent
      if (HAVE_PROC && /^\d+ \(.*\) Z/.test(fs.readFileSync(`/proc/${pid}/stat`, "utf8"))) {
        throw new Error("zombie");
      }
    } catch {
      console.log(`${name}: stopped (pid ${pid})`);
      return 0;
    }
    sleepMs(50);
  }
  console.error(`${name}: pid ${pid} did not stop within 5 s`);
  return 1;
}

// At exit: remove the pid file if it is still this process's.
export function removeOwnPidfile(file) {
  const rec = readPidfile(file);
  if (rec && rec.pid === process.pid) fs.rmSync(file, { force: true });
}

// The --detach log: a new file (mode 0600), open for reading and writing, so that the starter
// reads back through its own descriptor what the board writes, whatever the name points at later.
export function createLog(file) {
  fs.mkdirSync(path.dirname(file), { recursive: true });
  return createFile(file, { mode: 0o600, flags: C.O_RDWR });
}

// What has been written to an open log so far.
export function readLog(fd, max = 1 << 20) {
  const size = Math.min(fs.fstatSync(fd).size, max);
  const buf = Buffer.alloc(size);
  const n = size ? fs.readSync(fd, buf, 0, size, 0) : 0;
  return buf.subarray(0, n).toString("utf8");
}

// `--detach`: runs `script args` with this process's node and node options, detached, its output
// in a new log at logPath; waits for its banner (the line "  stop: ...") and prints it, with how to
// stop it.  Returns an exit code.
export async function runDetached({ script, args, logPath, stopHint, name = "virtual board", timeoutMs = 15000 }) {
  const log = createLog(logPath);
  const child = spawn(process.execPath, [...process.execArgv, script, ...args], {
    detached: true,
    stdio: ["ignore", log, log],
  });
  child.unref();
  const deadline = Date.now() + timeoutMs;
  while (Date.now() < deadline) {
    const text = readLog(log);
    if (/\n {2}stop: /.test(text)) {
      process.stdout.write(text.replace(/ {2}stop: .*\n/,
        `  stop: ${stopHint} (running in the background, pid ${child.pid}; log: ${logPath})\n`));
      return 0;
    }
    if (child.exitCode !== null) {
      process.stderr.write(text);
      return child.exitCode || 1;
    }
    await new Promise((r) => setTimeout(r, 50));
  }
  console.error(`${name}: did not start within ${timeoutMs / 1000} s; see ${logPath}`);
  return 1;
}
