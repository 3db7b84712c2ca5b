// Run a script in the real MicroPython WebAssembly VM (a 32-bit MicroPython 1.27) under node.
//
//   node tools/firmware/mpvm.mjs [--heap 1m] [--mount HOSTDIR:VMDIR ...] [--path VMDIR ...]
//                               [--symlink VMLINK=VMTARGET ...] (FILE.py | -c CODE)
//
// Host directories are copied into the VM's in-memory filesystem (lib/ -> /lib by default),
// so `import tempcomp` works as it does on a board. Exit status 1 on an uncaught Python
// exception (its traceback goes to stderr), 0 otherwise.
import fs from "node:fs";
import path from "node:path";
import { fileURLToPath, pathToFileURL } from "node:url";

const here = path.dirname(fileURLToPath(import.meta.url));
const repo = path.resolve(here, "..", "..");
const pkgDir =
  process.env.MPY_WASM_DIR ||
  path.join(here, "..", "node_modules", "@micropython", "micropython-webassembly-pyscript");
const { loadMicroPython } = await import(pathToFileURL(path.join(pkgDir, "micropython.mjs")).href);

function parseSize(s) {
  const m = /^(\d+)([kKmM]?)$/.exec(s);
  if (!m) throw new Error(`bad --heap size ${s}`);
  return parseInt(m[1], 10) * ({ k: 1024, m: 1048576 }[m[2].toLowerCase()] || 1);
}

let heap = 1048576;
const mounts = [];
const paths = [];
const symlinks = [];  // made in the VM's filesystem (tests of code that must not follow them)
let code = null;
const argv = process.argv.slice(2);
for (let i = 0; i < argv.length; i++) {
  const a = argv[i];
  if (a === "--heap") heap = parseSize(argv[++i]);
  else if (a === "--mount") mounts.push(argv[++i]);
  else if (a === "--path") paths.push(argv[++i]);
  else if (a === "--symlink") symlinks.push(argv[++i]);
  else if (a === "-c") code = argv[++i];
  else code = fs.readFileSync(a, "utf8");
}
if (code === null) code = fs.readFileSync(0, "utf8");
if (!mounts.some((m) => m.endsWith(":/lib"))) mounts.unshift(`${path.join(repo, "lib")}:/lib`);

const mp = await loadMicroPython({
  heapsize: heap,
  stdout: (s) => process.stdout.write(s + "\n"),
  stderr: (s) => process.stderr.write(s + "\n"),
});

function mkdirs(p) {
  let cur = "";
  for (const part of p.split("/").filter(Boolean)) {
    cur += "/" + part;
    try { mp.FS.mkdir(cur); } catch (e) { /* exists */ }
  }
}
function copyTree(src, dst) {
  mkdirs(dst);
  for (const ent of fs.readdirSync(src, { withFileTypes: true })) {
    if (ent.name === "__pycache__" || ent.name.startsWith(".")) continue;
    const s = path.join(src, ent.name);
    const d = dst + "/" + ent.name;
    if (ent.isDirectory()) copyTree(s, d);
    else if (ent.isFile()) mp.FS.writeFile(d, fs.readFileSync(s));
  }
}
for (const m of mounts) {
  const i = m.lastIndexOf(":");
  const src = path.resolve(m.slice(0, i));
  const dst = m.slice(i + 1);
  if (fs.statSync(src).isDirectory()) copyTree(src, dst);
  else { mkdirs(path.posix.dirname(dst)); mp.FS.writeFile(dst, fs.readFileSync(src)); }
}
for (const l of symlinks) {
  const i = l.indexOf("=");
  const link = l.slice(0, i);
  mkdirs(path.posix.dirname(link));
  mp.FS.symlink(l.slice(i + 1), link);
}
let prologue = "import sys\n";
for (const p of paths) prologue += `sys.path.insert(0, ${JSON.stringify(p)})\n`;
try {
  mp.runPython(prologue);
  mp.runPython(code);
} catch (e) {
  process.stderr.write((e.message || String(e)) + "\n");
  process.exitCode = 1;
}
