"""dvc.yaml against the stage scripts, read statically (no stage runs here).

- Each output path is declared once, in dvc.yaml: a stage gets every file it reads or writes from
  ``ctx.dep(name)`` / ``ctx.out(name)`` (blindspot.stage), each name matches exactly one path its
  dvc.yaml entry declares, every declared out is asked for, and no stage spells a path of its own.
  (At run time, under DVC, the runner also checks that each declared out was written:
  ``StageContext.check_outs``; tests/pipeline/test_repro.py compares the files a whole run
  leaves under data/ and reports/ with the declared outs.)
- Each stage's Python ``deps`` are exactly the project modules it imports, transitively (grimp's
  import graph of blindspot), and its script: changing one of them reruns the stage, and no other
  source file does. A folder may stand for its files only when the stage imports every module in
  it (:func:`python_deps` gives the list to paste).
"""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

import grimp
import pytest

import blindspot
from blindspot.stage import DeclaredFiles, read_dvc_stages

REPO = Path(__file__).resolve().parents[2]
STAGES = REPO / "stages"
SRC = Path(blindspot.__file__).resolve().parents[1]
# The runner and its glue: how a stage is called and logged, not what it computes. A stage's
# outputs do not depend on them, so its deps need not list them (nor what they import).
RUNNER = ("blindspot.cli", "blindspot.stage", "blindspot.runs")
# Suffixes of the pipeline's files: a string ending so in a stage is a hand-built path.
FILE_SUFFIXES = (".parquet", ".json", ".npz", ".csv", ".png", ".svg", ".md", ".pt", ".yaml")
PATH_IN_TEXT = re.compile(r"(^|[\s(`'\"])(data|reports)/")  # also inside messages

DVC_STAGES = read_dvc_stages(REPO)
STAGE_FILES = sorted(p.stem for p in STAGES.glob("*.py") if not p.stem.startswith("_"))


def test_every_stage_script_has_its_dvc_stage() -> None:
    missing = [s for s in STAGE_FILES if s not in DVC_STAGES]
    assert not missing, f"stages/ scripts without a stage in dvc.yaml: {missing}"


# --------------------------------------------------------------------------- declared paths


def _ctx_calls(tree: ast.AST) -> list[tuple[str, ast.expr]]:
    """(kind, argument) of every ``ctx.dep(...)`` / ``ctx.out(...)`` call."""
    calls = []
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr in ("dep", "out") and isinstance(node.func.value, ast.Name)
                and node.func.value.id == "ctx" and len(node.args) == 1):
            calls.append((node.func.attr, node.args[0]))
    return calls


def _pattern(arg: ast.expr) -> re.Pattern[str] | None:
    """The names an argument can take: a literal, or an f-string (its fields match anything)."""
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return re.compile(re.escape(arg.value))
    if isinstance(arg, ast.JoinedStr):
        parts = [re.escape(v.value) if isinstance(v, ast.Constant) else "[^/]+"
                 for v in arg.values]
        return re.compile("".join(parts))
    return None


def _matches(pattern: re.Pattern[str], path: str) -> bool:
    return any(pattern.fullmatch(tail) for tail in
               ["/".join(path.split("/")[i:]) for i in range(path.count("/") + 1)])


def declared_file_problems(source: str, files: DeclaredFiles) -> list[str]:
    """What a stage's ``ctx.dep``/``ctx.out`` names get wrong against its dvc.yaml entry."""
    tree = ast.parse(source)
    problems, asked = [], set()
    for kind, arg in _ctx_calls(tree):
        pattern = _pattern(arg)
        if pattern is None:
            problems.append(f"ctx.{kind}({ast.unparse(arg)}): name it by a literal or f-string")
            continue
        declared = files.deps if kind == "dep" else files.outs
        found = [p for p in declared if _matches(pattern, p)]
        if isinstance(arg, ast.Constant) and arg.value in found:
            found = [arg.value]  # the exact path wins, as in blindspot.stage
        if not found:
            problems.append(f"ctx.{kind}({ast.unparse(arg)}) matches no declared {kind}")
        if isinstance(arg, ast.Constant) and len(found) > 1:
            problems.append(f"ctx.{kind}({arg.value!r}) matches {found}")
        if kind == "out":
            asked.update(found)
    never = [p for p in files.outs if p not in asked]
    if never:
        problems.append(f"declared outs the stage never asks for: {never}")
    return problems


@pytest.mark.parametrize("stage", STAGE_FILES)
def test_stage_names_only_declared_files_and_every_declared_out(stage: str) -> None:
    problems = declared_file_problems((STAGES / f"{stage}.py").read_text(), DVC_STAGES[stage])
    assert not problems, f"stages/{stage}.py against dvc.yaml:\n  " + "\n  ".join(problems)


def _out_roots(tree: ast.AST) -> set[str]:
    """Names bound to an expression holding ``ctx.out(...)`` (a declared folder): assigned, or
    ``with atomic_dir(ctx.out("folder")) as name``."""
    roots = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and _ctx_calls(node.value):
            roots.update(t.id for t in node.targets if isinstance(t, ast.Name))
        if isinstance(node, ast.withitem) and isinstance(node.optional_vars, ast.Name) \
                and _ctx_calls(node.context_expr):
            roots.add(node.optional_vars.id)
    return roots


def _leftmost(node: ast.expr) -> ast.expr:
    while isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
        node = node.left
    return node


def hand_built_paths(source: str) -> list[str]:
    """Path-like strings of a stage other than ``ctx.dep``/``ctx.out`` names and file names
    inside a declared out folder (``ctx.out("recordings") / name / "detections.parquet"``)."""
    tree = ast.parse(source)
    allowed = {id(arg) for _, arg in _ctx_calls(tree)}
    for _, arg in _ctx_calls(tree):
        allowed.update(id(v) for v in ast.walk(arg))
    roots = _out_roots(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
            left = _leftmost(node)
            if (isinstance(left, ast.Name) and left.id in roots) or _ctx_calls(left):
                allowed.update(id(v) for v in ast.walk(node))
    for node in ast.walk(tree):  # docstrings are prose
        if isinstance(node, ast.Module | ast.FunctionDef | ast.ClassDef) and node.body \
                and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant):
            allowed.add(id(node.body[0].value))
    bad = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Constant) and isinstance(node.value, str)):
            continue
        if id(node) in allowed:
            continue
        text = node.value.strip()
        if PATH_IN_TEXT.search(text) or " " not in text and text.endswith(FILE_SUFFIXES):
            bad.append(f"line {node.lineno}: {text!r}")
    return bad


@pytest.mark.parametrize("stage", STAGE_FILES)
def test_stage_spells_no_path_of_its_own(stage: str) -> None:
    bad = hand_built_paths((STAGES / f"{stage}.py").read_text())
    assert not bad, (f"stages/{stage}.py builds paths by hand (declare them in dvc.yaml and ask "
                     f"ctx.dep/ctx.out):\n  " + "\n  ".join(bad))


BAD_STAGE = """
def run(cfg, ctx):
    a = pd.read_parquet(ctx.dep("truth.parquet"))
    b = pd.read_parquet(ctx.dep("missing.parquet"))
    write_json(ctx.out(f"m_{cfg.x}.json"), {})
    write_json("reports/metrics/extra.json", {})
    folder = ctx.out("folder") / cfg.name
    write_parquet(folder / "inside.parquet", a)
    raise ValueError(f"see data/simulate/truth.parquet for {a}")
"""


def test_the_path_checks_catch_what_they_promise() -> None:
    files = DeclaredFiles("bad", ("data/simulate/truth.parquet",),
                          ("reports/metrics/m_1.json", "data/bad/folder", "data/bad/never.csv"))
    problems = declared_file_problems(BAD_STAGE, files)
    assert problems == ["ctx.dep('missing.parquet') matches no declared dep",
                        "declared outs the stage never asks for: ['data/bad/never.csv']"]
    assert hand_built_paths(BAD_STAGE) == ["line 6: 'reports/metrics/extra.json'",
                                           "line 9: 'see data/simulate/truth.parquet for'"]


# --------------------------------------------------------------------------- deps cover imports


@cache
def _graph() -> grimp.ImportGraph:
    # imports under `if TYPE_CHECKING:` never run, so they cannot change what a stage computes
    return grimp.build_graph("blindspot", cache_dir=None, exclude_type_checking_imports=True)


def _module_file(module: str) -> Path:
    base = SRC.joinpath(*module.split("."))
    return base / "__init__.py" if base.is_dir() else base.with_suffix(".py")


def _has_code(module: str) -> bool:
    """False for a module holding only its docstring and dunder constants (``__version__``):
    running it changes nothing a stage computes."""
    body = ast.parse(_module_file(module).read_text()).body
    return any(not (isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)
                    or isinstance(n, ast.Assign) and isinstance(n.value, ast.Constant)
                    and all(isinstance(t, ast.Name) and t.id.startswith("__") for t in n.targets))
               for n in body)


def _direct_imports(path: Path, modules: set[str]) -> set[str]:
    """blindspot modules a script imports (``from pkg import mod`` counts as ``pkg.mod``)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.split(".")[0] == "blindspot")
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0 \
                and node.module.split(".")[0] == "blindspot":
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                found.add(sub if sub in modules else node.module)
    return found


def _is_runner(module: str) -> bool:
    return any(module == r or module.startswith(r + ".") for r in RUNNER)


def imported_modules(script: Path) -> set[str]:
    """Every blindspot module running ``script`` imports, transitively (with the packages whose
    ``__init__`` runs on the way), not following the runner (:data:`RUNNER`)."""
    graph = _graph()
    todo = [m for m in _direct_imports(script, graph.modules) if not _is_runner(m)]
    seen: set[str] = set()
    while todo:
        module = todo.pop()
        if module in seen or _is_runner(module):
            continue
        seen.add(module)
        parts = module.split(".")
        todo.extend(".".join(parts[:i]) for i in range(1, len(parts)))  # parent packages run too
        todo.extend(graph.find_modules_directly_imported_by(module))
    return {m for m in seen if _has_code(m)}


def _covered(path: str, deps: tuple[str, ...]) -> bool:
    return any(path == d or path.startswith(d.rstrip("/") + "/") for d in deps)


def uncovered_imports(stage: str, deps: tuple[str, ...]) -> list[str]:
    """The stage script and the modules it imports that ``deps`` do not cover."""
    script = f"stages/{stage}.py"
    missing = sorted(
        f"{m} ({_module_file(m).relative_to(REPO).as_posix()})"
        for m in imported_modules(STAGES / f"{stage}.py")
        if not _covered(_module_file(m).relative_to(REPO).as_posix(), deps))
    if not _covered(script, deps):
        missing.insert(0, script)
    return missing


def test_the_deps_check_follows_imports_transitively() -> None:
    """Live check: stages/paths.py reaches synth.path_measurement and, only through it, the
    chain's dsp.detections; without it among its deps that module is named."""
    found = imported_modules(STAGES / "paths.py")
    assert {"blindspot.synth.path_dataset", "blindspot.io"} <= found
    assert not any(_is_runner(m) for m in found)
    assert "blindspot.dsp.detections" in _graph().find_upstream_modules(
        "blindspot.synth.path_measurement")
    assert "blindspot.dsp.detections" in found
    assert "src/blindspot/dsp/detections.py" in DVC_STAGES["paths"].deps
    deps = tuple(d for d in DVC_STAGES["paths"].deps if d != "src/blindspot/dsp/detections.py")
    assert "blindspot.dsp.detections (src/blindspot/dsp/detections.py)" in \
        uncovered_imports("paths", deps)


def _source_files(folder: str) -> set[str]:
    return {p.relative_to(REPO).as_posix() for p in (REPO / folder).rglob("*.py")}


def python_deps(stage: str) -> list[str]:
    """The Python deps ``dvc.yaml`` should list for ``stage``: its script and every module of its
    import closure, a folder standing for its files where the stage imports all of them (modules
    without code, such as an ``__init__`` holding only a docstring, are in no closure but may sit
    in a listed folder: changing one changes nothing and DVC reruns for it)."""
    closure = {_module_file(m).relative_to(REPO).as_posix()
               for m in imported_modules(STAGES / f"{stage}.py")}
    out, done = [], set()
    for path in sorted(closure):
        parts = path.split("/")
        for i in range(3, len(parts)):           # src/blindspot/<room>..., widest folder first
            folder = "/".join(parts[:i])
            files = _source_files(folder)
            if all(f in closure or not _has_code_file(f) for f in files):
                if folder not in done:
                    out.append(folder)
                    done.add(folder)
                break
        else:
            out.append(path)
    return [f"stages/{stage}.py"] + [p for p in out if not any(
        p != d and p.startswith(d + "/") for d in done)]


def _has_code_file(path: str) -> bool:
    module = ".".join(Path(path).with_suffix("").parts[1:])
    return _has_code(module.removesuffix(".__init__"))


def dep_problems(stage: str) -> list[str]:
    """What a stage's deps get wrong against its import closure: a module it imports that no
    dep covers (changing it would not rerun the stage), a source dep it does not import (changing
    it reruns the stage for nothing), a folder of which it imports only part, a dep that neither
    exists nor is another stage's output."""
    deps = DVC_STAGES[stage].deps
    problems = [f"not listed: {m}" for m in uncovered_imports(stage, deps)]
    closure = {_module_file(m).relative_to(REPO).as_posix()
               for m in imported_modules(STAGES / f"{stage}.py")}
    produced = {o for s in DVC_STAGES.values() for o in s.outs}
    for dep in deps:
        if not (REPO / dep).exists() and dep not in produced:
            problems.append(f"{dep} (does not exist and no stage writes it)")
        elif dep.startswith("src/") and (REPO / dep).is_dir():
            extra = sorted(f for f in _source_files(dep) if f not in closure and _has_code_file(f))
            if extra:
                problems.append(f"{dep}/ holds modules the stage does not import: "
                                + ", ".join(extra))
        elif dep.startswith(("src/", "stages/")) and dep != f"stages/{stage}.py" \
                and dep not in closure:
            problems.append(f"{dep} (not imported)")
    return problems


@pytest.mark.parametrize("stage", STAGE_FILES)
def test_stage_deps_are_exactly_its_import_closure(stage: str) -> None:
    problems = dep_problems(stage)
    assert not problems, (
        f"dvc.yaml stage {stage!r}: its Python deps are not its import closure:\n  "
        + "\n  ".join(problems) + "\nlist exactly:\n      - " + "\n      - ".join(python_deps(stage)))


def test_the_exact_deps_check_refuses_more_and_fewer() -> None:
    """A dep too many (a module the stage does not import, a folder it imports in part) and a
    module too few are each named."""
    real = DVC_STAGES["table2"]
    assert "src/blindspot/traj/baselines.py" not in python_deps("table2")
    try:
        DVC_STAGES["table2"] = DeclaredFiles("table2", real.deps + (
            "src/blindspot/traj/baselines.py", "src/blindspot/dsp"), real.outs)
        problems = dep_problems("table2")
        assert "src/blindspot/traj/baselines.py (not imported)" in problems
        assert any(p.startswith("src/blindspot/dsp/ holds modules") for p in problems)
        DVC_STAGES["table2"] = DeclaredFiles("table2", tuple(
            d for d in real.deps if d != "src/blindspot/io.py"), real.outs)
        assert any("src/blindspot/io.py" in p for p in dep_problems("table2"))
    finally:
        DVC_STAGES["table2"] = real


def test_every_stage_file_is_at_most_60_lines() -> None:
    """Stages are thin entry points (../shared/DESIGN.md): the science and the bookkeeping live in
    the library."""
    over = {s: n for s in STAGE_FILES
            if (n := len((STAGES / f"{s}.py").read_text().splitlines())) > 60}
    assert not over, f"stage files over 60 lines: {over}"


@pytest.mark.parametrize("stage", STAGE_FILES)
def test_stage_imports_blindspot_before_numpy(stage: str) -> None:
    """A stage that imported numpy (pandas, ...) first would restart itself to get the pinned
    CPU kernels (blindspot.kernels): one more round of every import, ~4 s a stage."""
    import ast

    tree = ast.parse((STAGES / f"{stage}.py").read_text())
    imports = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))
               and not (isinstance(n, ast.ImportFrom) and n.module == "__future__")]
    first = imports[0]
    names = [a.name for a in first.names] if isinstance(first, ast.Import) else [first.module]
    assert names == ["blindspot"], f"stages/{stage}.py imports {names} before blindspot"
