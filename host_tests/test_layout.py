"""The tree explains itself: every tools/ folder says what it is for, and the import rules between
the roles hold (lib/ never imports the host; the diagnosis never sees how its benchmark is made)."""
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
