// A host directory that code on the board writes through (the virtual board's flash), walked
// so that nothing below its root is ever reached through a link.
//
// Someone with write access to the directory on the host (another program, a careless copy)
// may plant a symlink in it: flash/lib -> ~/.ssh.  A path-based mkdir -p, write or rm -r
// follows such a link in any component and writes or deletes outside the directory.  Here each
// component is opened on its own with O_NOFOLLOW | O_DIRECTORY, relative to the directory
// opened before it, and the operation runs on the last directory's descriptor: on Linux the
// name /proc/self/fd/N/<name> resolves <name> inside exactly the directory open as fd N (the
// kernel does not re-read the path that led there), so a link swapped in between the check and
// the use changes nothing: there is no check-then-use.  Without /proc (macOS) each component is
// lstat'ed before use instead, which refuses links but leaves a window between the two calls.
// The root itself is the user's choice (--flash) and is followed once, at open.

import fs from "node:fs";
import path from "node:path";

const C = fs.constants;
const DIR_FLAGS = C.O_RDONLY | C.O_DIRECTORY | C.O_NOFOLLOW;
const NEW_FILE = C.O_WRONLY | C.O_CREAT | C.O_EXCL | C.O_NOFOLLOW;
// O_NONBLOCK: a FIFO planted under a file's name must not block the reader
const READ_FILE = C.O_RDONLY | C.O_NOFOLLOW | C.O_NONBLOCK;

export const TMP_PREFIX = ".vboard-tmp-";
let tmpSeq = 0;

// A link (or something else that is not a directory) where a directory was expected.
export class LinkRefused extends Error {
  constructor(rel) {
    super(`${rel} is a link or not a directory on the host: not followed`);
    this.code = "ELINKREFUSED";
  }
}

function checkName(name) {
  if (!name || name === "." || name === ".." || name.includes("/") || name.includes("\0")) {
    throw new Error(`bad path component ${JSON.stringify(name)}`);
  }
}

function procFdWorks() {
  try {
    const fd = fs.openSync("/", C.O_RDONLY | C.O_DIRECTORY);
    try {
      return fs.statSync(`/proc/self/fd/${fd}/.`).isDirectory();
    } finally {
      fs.closeSync(fd);
    }
  } catch {
    return false;
  }
}

const VIA_PROC = procFdWorks();

export class HostDir {
  constructor(root) {
    this.root = path.resolve(root);
    this.raceFree = VIA_PROC;
  }

  // fn(dir), dir a path naming the directory `parts` below the root (created when `create`);
  // returns fn's result, or undefined when a directory is missing and not created.
  at(parts, create, fn) {
    return VIA_PROC ? this.#atFd(parts, create, fn) : this.#atLstat(parts, create, fn);
  }

  #atFd(parts, create, fn) {
    const fds = [];
    try {
      let fd = fs.openSync(this.root, C.O_RDONLY | C.O_DIRECTORY);
      fds.push(fd);
      for (let i = 0; i < parts.length; i++) {
        checkName(parts[i]);
        const p = `/proc/self/fd/${fd}/${parts[i]}`;
        try {
          fd = fs.openSync(p, DIR_FLAGS);
        } catch (e) {
          if (e.code === "ENOENT" && create) {
            fs.mkdirSync(p, 0o755); // mkdir never follows a link in its last component
            fd = fs.openSync(p, DIR_FLAGS);
          } else if (e.code === "ENOENT") {
            return undefined;
          } else if (e.code === "ELOOP" || e.code === "ENOTDIR") {
            throw new LinkRefused(parts.slice(0, i + 1).join("/"));
          } else {
            throw e;
          }
        }
        fds.push(fd);
      }
      return fn(`/proc/self/fd/${fd}`);
    } finally {
      for (const f of fds) fs.closeSync(f);
    }
  }

  #atLstat(parts, create, fn) {
    let dir = this.root;
    for (let i = 0; i < parts.length; i++) {
      checkName(parts[i]);
      const p = path.join(dir, parts[i]);
      let st = null;
      try {
        st = fs.lstatSync(p);
      } catch (e) {
        if (e.code !== "ENOENT") throw e;
      }
      if (!st) {
        if (!create) return undefined;
        fs.mkdirSync(p, 0o755);
        st = fs.lstatSync(p);
      }
      if (!st.isDirectory()) throw new LinkRefused(parts.slice(0, i + 1).join("/"));
      dir = p;
    }
    return fn(dir);
  }

  mkdir(parts) {
    this.at(parts, true, () => {});
  }

  // Whole contents, written to a new file that then replaces the name: a link at the name is
  // replaced, never written through; a reader never sees half a file.
  writeFile(parts, data) {
    const name = parts[parts.length - 1];
    checkName(name);
    this.at(parts.slice(0, -1), true, (dir) => {
      const tmp = `${dir}/${TMP_PREFIX}${process.pid}-${++tmpSeq}`;
      const fd = fs.openSync(tmp, NEW_FILE, 0o644);
      try {
        for (let n = 0; n < data.length; ) n += fs.writeSync(fd, data, n, data.length - n);
      } catch (e) {
        fs.closeSync(fd);
        fs.rmSync(tmp, { force: true });
        throw e;
      }
      fs.closeSync(fd);
      fs.renameSync(tmp, `${dir}/${name}`);
    });
  }

  // A file, or a directory and all below it; a link is removed itself (its target is not touched).
  remove(parts) {
    const name = parts[parts.length - 1];
    checkName(name);
    this.at(parts.slice(0, -1), false, (dir) => removeEntry(dir, name));
  }

  // rename(2) follows neither last component: a link at either name is moved or replaced.
  rename(from, to) {
    const a = from[from.length - 1], b = to[to.length - 1];
    checkName(a);
    checkName(b);
    this.at(from.slice(0, -1), false, (da) => {
      this.at(to.slice(0, -1), true, (db) => fs.renameSync(`${da}/${a}`, `${db}/${b}`));
    });
  }

  // Every regular file and directory below the root, depth first: visit(parts, null) for a
  // directory, visit(parts, bytes) for a file.  readFile(parts, size) is asked first whether a
  // file of that size is wanted (false: skipped unread).  Links, FIFOs, devices and the
  // writer's temporary files are skipped; skip(parts, why) hears of each.
  walk({ visit, want = () => true, skip = () => {} }) {
    const rec = (parts) => {
      this.at(parts, false, (dir) => {
        for (const name of fs.readdirSync(dir).sort()) {
          const p = [...parts, name];
          if (name.startsWith(TMP_PREFIX)) continue;
          const st = fs.lstatSync(`${dir}/${name}`);
          if (st.isDirectory()) {
            if (!want(p, 0, true)) {
              skip(p, "over the flash size");
              continue;
            }
            visit(p, null);
            try {
              rec(p);
            } catch (e) {
              if (!(e instanceof LinkRefused)) throw e;
              skip(p, "became a link while loading");
            }
          } else if (st.isFile()) {
            if (!want(p, st.size, false)) {
              skip(p, `${st.size} bytes: over the flash size`);
              continue;
            }
            const data = readRegular(`${dir}/${name}`, st.size);
            if (data) visit(p, data);
            else skip(p, "not a regular file when opened");
          } else {
            skip(p, st.isSymbolicLink() ? "a link" : "not a file or directory");
          }
        }
      });
    };
    rec([]);
  }
}

// At most `size` bytes of a regular file, or null if the name is no longer one.
function readRegular(p, size) {
  let fd;
  try {
    fd = fs.openSync(p, READ_FILE);
  } catch (e) {
    if (e.code === "ELOOP" || e.code === "ENXIO" || e.code === "ENOENT") return null;
    throw e;
  }
  try {
    if (!fs.fstatSync(fd).isFile()) return null;
    const buf = Buffer.alloc(size);
    let n = 0;
    while (n < size) {
      const k = fs.readSync(fd, buf, n, size - n, n);
      if (k === 0) break;
      n += k;
    }
    return buf.subarray(0, n);
  } finally {
    fs.closeSync(fd);
  }
}

function removeEntry(dir, name) {
  const p = `${dir}/${name}`;
  let st;
  try {
    st = fs.lstatSync(p);
  } catch (e) {
    if (e.code === "ENOENT") return;
    throw e;
  }
  if (!st.isDirectory()) {
    fs.unlinkSync(p);
    return;
  }
  if (VIA_PROC) {
    let fd;
    try {
      fd = fs.openSync(p, DIR_FLAGS);
    } catch (e) {
      if (e.code === "ELOOP" || e.code === "ENOTDIR") {
        fs.unlinkSync(p); // swapped for a link since the lstat: remove the link only
        return;
      }
      throw e;
    }
    try {
      const d = `/proc/self/fd/${fd}`;
      for (const n of fs.readdirSync(d)) removeEntry(d, n);
    } finally {
      fs.closeSync(fd);
    }
  } else {
    for (const n of fs.readdirSync(p)) removeEntry(p, n);
  }
  fs.rmdirSync(p);
}
