// The VM's files (used by vm_worker.mjs): its in-memory filesystem (Emscripten's MEMFS), with
// /flash mirrored to a directory on the host, and both bounded.
//
// Every change under /flash is mirrored when it happens (a file when it is closed), so a soft
// reset, a hard reset and a killed process all find the same files; at power-on the host
// directory is loaded back.  Code on the board reaches the whole MEMFS, not only the flash
// (vfs.VfsPosix('/') opens its root), so the limits sit at the filesystem's own entry points,
// whatever path or mount led there:
// - flash: every way a byte gets under /flash (a write, a new file or directory, a rename from
//   elsewhere, the loader at power-on) is counted against the flash size and refused beyond it
//   with ENOSPC, as a full board's flash refuses it;
// - RAM: every file, directory and file's storage anywhere in the MEMFS (/tmp, files open but
//   unlinked) is counted, and growth beyond `ramLimit` is refused with ENOSPC, so board code
//   cannot grow the host process's memory through files;
// - the host directory is written through hostdir.mjs: never through a link.

import path from "node:path";
import { HostDir } from "./hostdir.mjs";

export const FLASH = "/flash";
// Bytes as a LittleFS/FAT volume counts them: whole blocks per file and per directory, a file at
// least one (the same count as vboard_rt.FlashVfs.statvfs).
export const BLOCK = 4096;
const ENOSPC_WASI = 51; // mapped to Linux ENOSPC (28) at the syscall boundary
const O_APPEND = 1024;

const blocksOf = (size) => Math.ceil(size / BLOCK) * BLOCK;
const fileBlocks = (size) => Math.max(BLOCK, blocksOf(size));

export function installFiles({ FS, flashDir, flashLimit, ramDisk, log }) {
  const host = new HostDir(flashDir);
  const full = () => new FS.ErrnoError(ENOSPC_WASI);

  // ------------------------------------------------------------ paths

  // The canonical absolute path of p (its directory looked up, links and .. resolved), or null.
  function canon(p) {
    try {
      const abs = path.posix.resolve(FS.cwd(), p);
      if (abs === "/") return "/";
      const dir = FS.lookupPath(path.posix.dirname(abs), { follow: true }).node;
      return path.posix.join(FS.getPath(dir), path.posix.basename(abs));
    } catch {
      return null;
    }
  }

  // The path's components below /flash ([] for /flash itself), or null if it is not in flash.
  function flashParts(c) {
    if (c === FLASH) return [];
    if (!c || !c.startsWith(FLASH + "/")) return null;
    return c.slice(FLASH.length + 1).split("/");
  }

  function lookup(p) {
    try {
      return FS.lookupPath(p, { follow: false }).node;
    } catch {
      return null;
    }
  }

  // ------------------------------------------------------------ accounting

  function flashSize(p) {
    const st = FS.lstat(p);
    if (!FS.isDir(st.mode)) return fileBlocks(st.size);
    let n = BLOCK;
    for (const name of FS.readdir(p)) {
      if (name !== "." && name !== "..") n += flashSize(p + "/" + name);
    }
    return n;
  }

  const flashUsed = () => flashSize(FLASH) - BLOCK;

  // Storage MEMFS holds for a file: its array, which grows ahead of the data.
  const capacityOf = (node) => (node.contents && ArrayBuffer.isView(node.contents) ? node.contents.length : node.usedBytes || 0);

  // MEMFS.expandFileStorage's growth rule: double below 1 MiB, then 1/8 more.
  function grownCapacity(node, end) {
    const prev = capacityOf(node);
    if (prev >= end) return prev;
    let cap = Math.max(end, (prev * (prev < 1048576 ? 2 : 1.125)) >>> 0);
    if (prev !== 0) cap = Math.max(cap, 256);
    return cap;
  }

  // Every node of the MEMFS (reachable, or open though unlinked): a block each, plus files' storage.
  function ramUsed() {
    const seen = new Set();
    let n = 0;
    const visit = (node) => {
      if (!node || seen.has(node)) return;
      seen.add(node);
      n += BLOCK;
      if (FS.isFile(node.mode)) n += blocksOf(capacityOf(node));
      else if (FS.isDir(node.mode)) {
        const c = node.contents;
        if (c && typeof c === "object" && !ArrayBuffer.isView(c)) for (const k of Object.keys(c)) visit(c[k]);
        if (node.mounted) visit(node.mounted.root);
      }
    };
    visit(FS.root);
    for (const s of FS.streams) if (s) visit(s.node);
    return n;
  }

  // The flash is loaded (at most its size) before the limits go in; the RAM allowance is what
  // is there then plus the RAM disk plus room for the flash to fill (its arrays grow to 2x).
  function load() {
    let used = 0, skipped = 0;
    const shown = [];
    host.walk({
      want: (parts, size, isDir) => {
        const cost = isDir ? BLOCK : fileBlocks(size);
        if (used + cost > flashLimit) return false;
        used += cost;
        return true;
      },
      visit: (parts, data) => {
        const v = FLASH + "/" + parts.join("/");
        if (data === null) FS.mkdir(v);
        else FS.writeFile(v, data);
      },
      skip: (parts, why) => {
        skipped++;
        if (shown.length < 5) shown.push(`${parts.join("/")} (${why})`);
      },
    });
    if (skipped) {
      log(`flash: ${skipped} host entr${skipped === 1 ? "y" : "ies"} not loaded: ${shown.join(", ")}` +
        (skipped > shown.length ? ", ..." : ""));
    }
  }

  // ------------------------------------------------------------ mirror

  function mirror(what, p, fn) {
    try {
      fn();
    } catch (e) {
      log(`flash mirror: ${what} ${p}: ${e.message}`);
    }
  }

  // A file or a tree, now at VM path c (in flash), written to the host.
  function persistTree(c, parts) {
    const node = lookup(c);
    if (!node) return;
    if (FS.isDir(node.mode)) {
      mirror("mkdir", c, () => host.mkdir(parts));
      for (const name of FS.readdir(c)) {
        if (name !== "." && name !== "..") persistTree(c + "/" + name, [...parts, name]);
      }
    } else if (FS.isFile(node.mode)) {
      mirror("write", c, () => host.writeFile(parts, FS.readFile(c)));
    }
  }

  let installed = false;
  function install() {
    if (installed) return;
    installed = true;
    const ramLimit = ramUsed() + ramDisk + 2 * flashLimit;

    const origWrite = FS.write;
    FS.write = function (stream, buffer, offset, length, position, canOwn) {
      const node = stream.node;
      if (node && FS.isFile(node.mode) && length > 0) {
        const size = node.usedBytes || 0;
        const pos = typeof position === "number" ? position : stream.position;
        const end = (stream.flags & O_APPEND) !== 0 ? size + length : pos + length;
        if (end > size) {
          const cap = capacityOf(node), grown = grownCapacity(node, end);
          if (grown > cap && ramUsed() - blocksOf(cap) + blocksOf(grown) > ramLimit) throw full();
          // the node's path now (it may have been renamed into flash since it was opened)
          if (fileBlocks(end) > fileBlocks(size) && flashParts(FS.getPath(node)) &&
              flashUsed() - fileBlocks(size) + fileBlocks(end) > flashLimit) throw full();
        }
      }
      return origWrite.call(FS, stream, buffer, offset, length, position, canOwn);
    };

    // every new file and directory (open with O_CREAT, mkdir)
    const origMknod = FS.mknod;
    FS.mknod = function (p, mode, dev) {
      if (ramUsed() + BLOCK > ramLimit) throw full();
      if (flashParts(canon(p)) && flashUsed() + BLOCK > flashLimit) throw full();
      return origMknod.call(FS, p, mode, dev);
    };

    const origMkdir = FS.mkdir;
    FS.mkdir = function (p, mode) {
      const r = origMkdir.call(FS, p, mode);
      const parts = flashParts(canon(p));
      if (parts && parts.length) mirror("mkdir", p, () => host.mkdir(parts));
      return r;
    };

    const origRename = FS.rename;
    FS.rename = function (a, b) {
      const ca = canon(a), cb = canon(b);
      const pa = flashParts(ca), pb = flashParts(cb);
      if (pb && !pa && ca) {
        // into flash from elsewhere (/tmp): all of it counts, less what it replaces
        const incoming = flashSize(ca);
        const replaced = lookup(cb) ? flashSize(cb) : 0;
        if (flashUsed() - replaced + incoming > flashLimit) throw full();
      }
      const r = origRename.call(FS, a, b);
      if (pa && pb && pa.length && pb.length) mirror("rename", a, () => host.rename(pa, pb));
      else if (pb && pb.length) persistTree(cb, pb);
      else if (pa && pa.length) mirror("remove", a, () => host.remove(pa));
      return r;
    };

    for (const name of ["rmdir", "unlink"]) {
      const orig = FS[name];
      FS[name] = function (p) {
        const r = orig.call(FS, p);
        const parts = flashParts(canon(p));
        if (parts && parts.length) mirror(name, p, () => host.remove(parts));
        return r;
      };
    }

    const origClose = FS.close;
    FS.close = function (stream) {
      const node = stream.node;
      const wrote = (stream.flags & 3) !== 0 && node && FS.isFile(node.mode);
      const r = origClose.call(FS, stream);
      if (wrote) {
        const c = FS.getPath(node);
        const parts = flashParts(c);
        // only if the name still leads to this file (not removed or replaced while open)
        if (parts && parts.length && lookup(c) === node) mirror("write", c, () => host.writeFile(parts, FS.readFile(c)));
      }
      return r;
    };
  }

  return { load, install, flashUsed, ramUsed };
}
