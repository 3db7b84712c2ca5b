"""The tree explains itself: every tools/ folder says what it is for, and the import rules between
the roles hold (lib/ never imports the host; the diagnosis never sees how its benchmark is made);
inside lib/, imports go one way (no cycles) and no module takes another's private names or reaches
into another's objects for their private attributes."""
import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

# folder -> the tools.* packages its Python may import ("tools" alone = the root's REPO/LIB)
ALLOWED = {
    "tools/fit": ("tools", "tools.fit", "tools.sim"),
    "tools/sim": ("tools.sim",),
    "tools/simgap": ("tools", "tools.simgap", "tools.firmware"),
    "tools/gapbench/gen.py": ("tools.gapbench",),
    # the wander generator: written from physics and the public schema, nothing of ours
    "tools/gapbench/wander.py": (),
    # its scoring runs the diagnosis only through the front door (tools.__main__), as a black box
    "tools/gapbench/wandercheck.py": ("tools", "tools.gapbench"),
    "tools/gapbench": ("tools", "tools.gapbench", "tools.simgap"),
    "tools/firmware": ("tools", "tools.firmware"),
    "tools/board": ("tools", "tools.board", "tools.firmware"),
    "tools/vboard": (),
    "tools/pico": (),  # pico_bus.py runs in the world's MicroPython VM
    "tools/bench": ("tools",),  # anything under tools
    "tools/demo": ("tools",),
    "tools/__main__.py": ("tools",),
    "tools/__init__.py": (),
    "tools/hostio.py": (),
    "lib": (),
    "boards": (),
}
# never imported by anything outside themselves
LEAVES = ("tools.bench", "tools.demo")
FOREIGN = ("host_tests",)  # no shipped code imports the tests
NOT_ON_DEVICE = ("numpy", "scipy", "dataclasses", "tools", "boards", "host_tests")


def imports(path):
    tree = ast.parse(path.read_text(), str(path))
    pkg = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.rsplit(".", node.level - 1)[0] if node.level > 1 else pkg
                yield node.lineno, base + ("." + node.module if node.module else "")
            else:
                yield node.lineno, node.module
                if node.module == "tools":
                    for a in node.names:
                        yield node.lineno, "tools." + a.name


def allowed_import(mod, allowed):
    parts = mod.split(".")
    if len(parts) == 1 or not (ROOT / "tools" / parts[1]).is_dir():
        return "tools" in allowed  # the root package's own names (REPO, LIB)
    return any(a != "tools" and (mod == a or mod.startswith(a + ".")) for a in allowed)


def rule_for(rel):
    best = None
    for key in ALLOWED:
        if rel == key or rel.startswith(key + "/"):
            if best is None or len(key) > len(best):
                best = key
    return best


def sources():
    for top in ("lib", "boards", "tools"):
        for p in sorted((ROOT / top).rglob("*.py")):
            if "node_modules" not in p.parts:
                yield p


def test_every_source_has_a_rule():
    missing = [str(p.relative_to(ROOT)) for p in sources() if rule_for(str(p.relative_to(ROOT))) is None]
    assert not missing, "add these to ALLOWED in host_tests/test_layout.py: %s" % missing


def test_import_rules():
    bad = []
    for p in sources():
        rel = str(p.relative_to(ROOT))
        key = rule_for(rel)
        allowed = ALLOWED[key]
        for line, mod in imports(p):
            where = "%s:%d imports %s" % (rel, line, mod)
            if mod.split(".")[0] in FOREIGN:
                bad.append(where + " (shipped code never imports the tests)")
            if key in ("lib", "boards"):
                if mod.split(".")[0] in NOT_ON_DEVICE:
                    bad.append(where + " (runs on the board: no host packages)")
                continue
            if not mod.startswith("tools"):
                continue
            if key in ("tools/bench", "tools/demo"):
                continue
            if any(mod.startswith(leaf) for leaf in LEAVES):
                bad.append(where + " (bench/ and demo/ are leaves: nothing imports them)")
            elif not allowed_import(mod, allowed):
                bad.append(where + " (%s may import only %s)" % (key, ", ".join(allowed) or "nothing from tools"))
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("pkg", sorted(p.parent.name for p in (ROOT / "tools").glob("*/__init__.py")))
def test_each_tools_package_says_what_it_is(pkg):
    doc = ast.get_docstring(ast.parse((ROOT / "tools" / pkg / "__init__.py").read_text()))
    assert doc and len(doc) > 40, "tools/%s/__init__.py needs a docstring: what it is for" % pkg


def test_each_folder_opens_with_a_line():
    folders = [d for d in (ROOT / "tools").iterdir() if d.is_dir() and d.name not in ("node_modules", "__pycache__")]
    folders += [d for d in (ROOT / "host_tests").iterdir() if d.is_dir() and d.name != "__pycache__"]
    bare = [str(d.relative_to(ROOT)) for d in folders
            if not (d / "README.md").exists() and not (d / "__init__.py").exists()]
    assert not bare, "folders without a README.md or __init__.py docstring: %s" % bare


def test_the_rules_catch_a_violation(tmp_path):
    # the checker itself: a simgap module importing the benchmark's generator is refused
    fake = ROOT / "tools" / "simgap" / "_layout_probe.py"
    fake.write_text("from tools.gapbench import gen\n")
    try:
        with pytest.raises(AssertionError, match="tools/simgap may import only"):
            test_import_rules()
    finally:
        fake.unlink()


# ---- lib/: one-way imports between the on-device modules ------------------------------------
# Each family reads bottom-up (README "Layers"): a module imports only modules below it, at module
# level or inside a function alike (a function-level import is how a board defers loading code,
# not a licence to import upwards), and no module imports another's private (_name) helpers: a
# helper two modules share is a public name of the module that owns it.


def lib_modules(lib):
    """{dotted name: path} of every module under lib ('tempcomp', 'tempcomp.store', ...)."""
    out = {}
    for p in sorted(pathlib.Path(lib).rglob("*.py")):
        parts = p.relative_to(lib).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def _package_of(name, path):
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def lib_imports(lib):
    """(importer, imported module, line, names taken from it, aliases bound to it) for every import of
    a lib module by a lib module, wherever the import statement stands."""
    mods = lib_modules(lib)
    out = []
    for name, path in mods.items():
        tree = ast.parse(path.read_text(), str(path))
        pkg = _package_of(name, path)
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    if a.name in mods:
                        # `import a.b` binds a; `import a.b as c` binds c to a.b
                        out.append((name, a.name, node.lineno, (), (a.asname,) if a.asname else ()))
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = pkg.split(".")[: len(pkg.split(".")) - (node.level - 1)]
                    base = ".".join(up + ([node.module] if node.module else []))
                taken = []
                for a in node.names:
                    sub = base + "." + a.name
                    if sub in mods:  # `from tempcomp import store`: the submodule itself
                        out.append((name, sub, node.lineno, (), (a.asname or a.name,)))
                    else:
                        taken.append(a.name)
                if base in mods and taken:
                    out.append((name, base, node.lineno, tuple(taken), ()))
    return out


def _private(n):
    return n.startswith("_") and not (n.startswith("__") and n.endswith("__"))


def lib_cycles(lib):
    """Every import cycle among lib modules, each as a list of 'a -> b (file:line)' steps."""
    graph = {}
    where = {}
    for a, b, line, _, _ in lib_imports(lib):
        if a != b:
            graph.setdefault(a, set()).add(b)
            where.setdefault((a, b), line)
    # Tarjan's strongly connected components; a component of two or more modules is a cycle
    index, low, stack, on, comps = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    mods = lib_modules(lib)
    out = []
    for comp in comps:
        steps = ["%s -> %s (%s:%d)" % (a, b, mods[a].relative_to(lib), where[(a, b)])
                 for a in comp for b in sorted(graph.get(a, ())) if b in comp]
        out.append(steps)
    return out


def lib_private_imports(lib):
    """'file:line: name' for every private name one lib module takes from another: imported by
    name, or read as an attribute of a module it imported."""
    mods = lib_modules(lib)
    bad = []
    aliases = {}
    for a, b, line, taken, bound in lib_imports(lib):
        for n in taken:
            if _private(n) and a != b:
                bad.append("%s:%d imports %s from %s" % (mods[a].relative_to(lib), line, n, b))
        for al in bound:
            aliases.setdefault(a, {})[al] = b
    for name, path in mods.items():
        tree = ast.parse(path.read_text(), str(path))
        known = aliases.get(name, {})
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Attribute) and _private(node.attr)):
                continue
            # the dotted name the attribute is read from: st._crc, tempcomp.store._crc
            chain = []
            v = node.value
            while isinstance(v, ast.Attribute):
                chain.append(v.attr)
                v = v.value
            if not isinstance(v, ast.Name):
                continue
            dotted = ".".join([v.id] + chain[::-1])
            target = known.get(v.id) if not chain else (dotted if dotted in mods else None)
            if not chain and target is None and v.id in mods and v.id != name:
                target = v.id
            if target is not None and target != name:
                bad.append("%s:%d reads %s.%s" % (path.relative_to(lib), node.lineno, target, node.attr))
    return bad


def test_lib_imports_have_no_cycles():
    cycles = lib_cycles(ROOT / "lib")
    assert not cycles, "import cycles among lib/ modules (a module may import only what lies below it):\n" + \
        "\n".join("  cycle: " + "; ".join(c) for c in cycles)


def test_lib_modules_import_no_private_names():
    bad = lib_private_imports(ROOT / "lib")
    assert not bad, "private names used across lib/ modules (make them public in the module that owns " \
        "them, or move them to the one that uses them):\n  " + "\n  ".join(bad)


def test_the_lib_rules_catch_a_violation(tmp_path):
    # the checkers themselves, on a tree made here: a cycle through a function-level import, and a
    # private helper taken by name and as a module attribute
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "low.py").write_text("def f():\n    from pkg import high\n    return high\n_helper = 1\n")
    (pkg / "high.py").write_text("from pkg.low import f, _helper\n")
    (pkg / "sub" / "__init__.py").write_text("from .. import low as L\nx = L._helper\n")
    (pkg / "sub" / "leaf.py").write_text("import pkg.low\ny = pkg.low._helper\nfrom . import other\n")
    (pkg / "sub" / "other.py").write_text("from pkg.sub import leaf\n")
    cycles = lib_cycles(tmp_path)
    assert sorted(sorted(c) for c in cycles) == [
        ["pkg.high -> pkg.low (pkg/high.py:1)", "pkg.low -> pkg.high (pkg/low.py:2)"],
        ["pkg.sub.leaf -> pkg.sub.other (pkg/sub/leaf.py:3)", "pkg.sub.other -> pkg.sub.leaf (pkg/sub/other.py:1)"],
    ]
    assert sorted(lib_private_imports(tmp_path)) == [
        "pkg/high.py:1 imports _helper from pkg.low",
        "pkg/sub/__init__.py:2 reads pkg.low._helper",
        "pkg/sub/leaf.py:2 reads pkg.low._helper",
    ]


# ---- lib/: no module reaches into another's objects -------------------------------------------
# A private attribute (self._x, a _method, a class-level _NAME) is its module's business: when the
# driver needs a Compensator's per-sample numbers, fixedpoint gives them a public name (burst3,
# export()). Read statically: an obj._x read or written in a module that never defines _x itself,
# while another lib module does. (When both define an _x of the same name the owner cannot be
# told without types; that case is not flagged.)

# A class may take methods from another module: tempcomp.augment installs its kernels' functions
# (augment_pure.apply, augment_native.apply: module-level functions whose first parameter is self)
# on Augmented when a model first needs them, so that a board holds only the kernel it runs.
# Such a function is the class's own method, and its self._x is the class's: allowed when the
# installing module defines _x, and flagged when nothing there does (a private renamed on one
# side would otherwise break the other silently).


# Known, and not yet fixed: the augmented model's set-up (augment.py) and its pure kernel's step on
# a new reading (augment_pure.py) read fixedpoint's Compensator and Poly internals (48 reads on
# 2026-11-27). Public methods for them in fixedpoint (tried: shape(), gains_into(), update_ints())
# made fixedpoint.py's .py import keep 2.7 KB more (a new interned-name pool) and tempcomp.mlx90609
# and tempcomp.augment no longer imported from .py on the AN385 (docs/ram.md). Only these reads
# are excepted; the test below fails once they are gone, so that this list only shrinks.
KNOWN_PRIVATE_READS = ("tempcomp/augment.py:", "tempcomp/augment_pure.py:")
KNOWN_OWNER = "tempcomp.fixedpoint"


def _known(b):
    return b.startswith(KNOWN_PRIVATE_READS) and "(defined in " in b and KNOWN_OWNER in b.rsplit("(defined in ", 1)[1]


def lib_private_attribute_owners(lib):
    """{module: private attribute names it defines}: assigned on self, or a method or class
    attribute in one of its classes."""
    out = {}
    for name, path in lib_modules(lib).items():
        own = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ClassDef):
                for b in node.body:
                    if isinstance(b, (ast.FunctionDef, ast.AsyncFunctionDef)) and _private(b.name):
                        own.add(b.name)
                    elif isinstance(b, ast.Assign):
                        own.update(t.id for t in b.targets if isinstance(t, ast.Name) and _private(t.id))
            elif (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store) and _private(node.attr)
                  and isinstance(node.value, ast.Name) and node.value.id == "self"):
                own.add(node.attr)
        out[name] = own
    return out


def lib_installed_methods(lib):
    """{module: modules that install its functions as methods of one of their classes}, from
    assignments `Cls.name = module.function` (Cls a class of the installing module)."""
    mods = lib_modules(lib)
    bound = {}
    for a, b, _, _, names in lib_imports(lib):
        for al in names:
            bound.setdefault(a, {})[al] = b
    out = {}
    for name, path in mods.items():
        tree = ast.parse(path.read_text(), str(path))
        classes = {n.name for n in tree.body if isinstance(n, ast.ClassDef)}
        for node in ast.walk(tree):
            if not isinstance(node, ast.Assign) or not isinstance(node.value, ast.Attribute):
                continue
            v = node.value
            src = bound.get(name, {}).get(v.value.id) if isinstance(v.value, ast.Name) else None
            for t in node.targets:
                if (src and src != name and isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name)
                        and t.value.id in classes):
                    out.setdefault(src, set()).add(name)
    return out


def _self_methods(tree):
    """Module-level functions whose first parameter is self, and the nodes in them."""
    for f in tree.body:
        if isinstance(f, ast.FunctionDef) and f.args.args and f.args.args[0].arg == "self":
            for node in ast.walk(f):
                yield node


def lib_private_attribute_reads(lib):
    """'file:line reads|writes obj._x (defined in owner)' for every access in one lib module of a
    private attribute that only other lib modules define; in a method installed from another module,
    'reads self._x (not defined by its class in owner)' for a private its class does not have."""
    mods = lib_modules(lib)
    owners = lib_private_attribute_owners(lib)
    hosts = lib_installed_methods(lib)
    bad = []
    for name, path in mods.items():
        tree = ast.parse(path.read_text(), str(path))
        installed = set()
        if name in hosts:
            own = set(owners[name]).union(*(owners[h] for h in hosts[name]))
            for node in _self_methods(tree):
                if (isinstance(node, ast.Attribute) and _private(node.attr) and isinstance(node.value, ast.Name)
                        and node.value.id == "self"):
                    installed.add(node)
                    if node.attr not in own:
                        bad.append("%s:%d %s %s (not defined by its class in %s)" % (
                            path.relative_to(lib), node.lineno,
                            "writes" if isinstance(node.ctx, ast.Store) else "reads", ast.unparse(node),
                            ", ".join(sorted(hosts[name]))))
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Attribute) and _private(node.attr)) or node.attr in owners[name]:
                continue
            if node in installed:
                continue
            others = sorted(m for m, own in owners.items() if m != name and node.attr in own)
            if others:
                bad.append("%s:%d %s %s (defined in %s)" % (
                    path.relative_to(lib), node.lineno, "writes" if isinstance(node.ctx, ast.Store) else "reads",
                    ast.unparse(node), ", ".join(others)))
    return sorted(bad)


def test_lib_modules_read_no_private_attributes_of_another():
    bad = [b for b in lib_private_attribute_reads(ROOT / "lib") if not _known(b)]
    assert not bad, "private attributes used across lib/ modules (give them a public name or a method in " \
        "the module that owns them):\n  " + "\n  ".join(bad)


def test_the_known_private_reads_are_still_there():
    found = [b for b in lib_private_attribute_reads(ROOT / "lib") if _known(b)]
    assert found, "no reads of %s internals left in %s: remove them from KNOWN_PRIVATE_READS" % (
        KNOWN_OWNER, KNOWN_PRIVATE_READS)


def test_the_augmented_models_kernels_are_its_installed_methods():
    # what the rule above lets through, named: augment installs both kernels' functions on Augmented
    hosts = lib_installed_methods(ROOT / "lib")
    assert hosts.get("tempcomp.augment_pure") == {"tempcomp.augment"}
    assert hosts.get("tempcomp.augment_native") == {"tempcomp.augment"}


def test_the_private_attribute_rule_catches_a_violation(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "core.py").write_text(
        "class Comp:\n    _LIMIT = 3\n    def __init__(self):\n        self._p = [0]\n        self.public = 1\n"
        "    def _step(self):\n        return self._p\n")
    (pkg / "driver.py").write_text(
        "from pkg.core import Comp\nclass Driver:\n    def __init__(self):\n        self._c = Comp()\n"
        "    def read(self):\n        c = self._c\n        c._step()\n        c._p = c.public\n"
        "        return c._p[0], Comp._LIMIT\n")
    (pkg / "mixin.py").write_text("class Extra:\n    def more(self):\n        return self._c\n")
    # methods installed on a class from another module: their self is that class's (_q, _go),
    # a private the class lacks is flagged (_gone), and so is another object's (c._p, w._go)
    (pkg / "kern.py").write_text(
        "def run(self, c):\n    self._q = self._go()\n    return self._gone, c._p\n"
        "def helper(w):\n    return w._go\n")
    (pkg / "host.py").write_text(
        "from pkg import kern\nclass Model:\n    def __init__(self):\n        self._q = 0\n"
        "    def _go(self):\n        return 1\nModel.run = kern.run\n")
    assert lib_private_attribute_reads(tmp_path) == [
        "pkg/driver.py:7 reads c._step (defined in pkg.core)",
        "pkg/driver.py:8 writes c._p (defined in pkg.core)",
        "pkg/driver.py:9 reads Comp._LIMIT (defined in pkg.core)",
        "pkg/driver.py:9 reads c._p (defined in pkg.core)",
        "pkg/kern.py:3 reads c._p (defined in pkg.core)",
        "pkg/kern.py:3 reads self._gone (not defined by its class in pkg.host)",
        "pkg/kern.py:5 reads w._go (defined in pkg.host)",
        "pkg/mixin.py:3 reads self._c (defined in pkg.driver)",
    ]
    assert lib_installed_methods(tmp_path) == {"pkg.kern": {"pkg.host"}}


def readme_layers():
    """{module: layer number} from README's "Layers" list (bottom = 1), module names in backquotes."""
    import re

    text = (ROOT / "README.md").read_text()
    sec = text.split("### Layers: `lib/` from the ground up", 1)[1].split("\n#", 1)[0]
    mods = {n.rpartition(".")[2] for n in lib_modules(ROOT / "lib") if n != "tempcomp"}
    out = {}
    for num, body in re.findall(r"^(\d+)\. (.*?)(?=^\d+\. |\Z)", sec, re.S | re.M):
        for name in re.findall(r"`([a-z0-9_]+)`", body):
            if name in mods:
                out.setdefault(name, int(num))
    return out


def test_readme_layers_name_every_module_below_what_imports_it():
    layer = readme_layers()
    mods = {n.rpartition(".")[2] for n in lib_modules(ROOT / "lib") if n != "tempcomp"}
    assert sorted(mods - set(layer)) == [], "modules missing from README's Layers list"
    up = ["%s (layer %d) imports %s (layer %d)" % (a, layer[a.rpartition(".")[2]], b, layer[b.rpartition(".")[2]])
          for a, b, _, _, _ in lib_imports(ROOT / "lib")
          if a != "tempcomp" and b != "tempcomp"
          and layer[a.rpartition(".")[2]] < layer[b.rpartition(".")[2]]]
    assert not up, "README's Layers list puts these imports upwards:\n" + "\n".join(up)

@pytest.mark.parametrize("mod", ["tools.simgap.diagnose", "tools.simgap", "tools.gapbench.gen", "tools.gapbench.wandercheck"])
def test_the_wander_generator_may_see_nothing_of_ours(mod):
    # neither the diagnosis nor the project's own generator: the rule refuses them, and today's
    # file imports nothing from tools at all
    rule = ALLOWED[rule_for("tools/gapbench/wander.py")]
    assert not allowed_import(mod, rule)
    assert not [m for _, m in imports(ROOT / "tools" / "gapbench" / "wander.py") if m.startswith("tools")]


def test_wander_scoring_imports_no_diagnosis_internals():
    path = ROOT / "tools" / "gapbench" / "wandercheck.py"
    mods = {m for _, m in imports(path)}
    assert not any(m.startswith("tools.simgap") for m in mods), mods
    assert "tools.__main__" in mods  # the front door runs the diagnosis
