"""The house rules of study, checked: the layer contracts in pyproject.toml (import-linter), no import cycle, no
module over 460 lines (ruff-formatted), the map of the house in docs/architecture.md up to date, and a README short
enough to read."""

import ast
import textwrap
from pathlib import Path

from importlinter.cli import lint_imports

ROOT = Path(__file__).resolve().parents[1]
MAX_LINES = 460


def test_layer_contracts_hold():
    """import-linter's contracts of pyproject.toml: lower layers never import upper ones, no cycles."""
    assert lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True) == 0


def test_layer_contract_catches_an_upward_import(tmp_path, monkeypatch):
    """The same kind of contract on a two-layer toy package, with the lower layer importing the upper: broken."""
    pkg = tmp_path / "toy"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "high.py").write_text("X = 1\n")
    (pkg / "low.py").write_text("from toy.high import X\n")
    (tmp_path / "toy.toml").write_text(
        textwrap.dedent("""
        [tool.importlinter]
        root_package = "toy"
        [[tool.importlinter.contracts]]
        name = "layers"
        type = "layers"
        layers = ["toy.high", "toy.low"]
    """)
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    assert lint_imports(config_filename=str(tmp_path / "toy.toml"), no_cache=True) == 1


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the nodes inside ``if TYPE_CHECKING:`` blocks (imports for annotations only)."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            t = node.test
            if getattr(t, "id", None) == "TYPE_CHECKING" or getattr(t, "attr", None) == "TYPE_CHECKING":
                skip |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    return skip


def import_graph(root: Path, package: str, *, typing_only: bool = False) -> dict[str, set[str]]:
    """module → the modules of ``package`` it imports, from every import statement (at the top, in functions, in
    classes), except inside ``if TYPE_CHECKING:`` (with ``typing_only``: those too). ``from pkg import name`` is an
    edge to ``pkg`` (its ``__init__`` runs, and the name may be one it re-exports) and to the module ``pkg.name``
    where there is one; ``import pkg.mod`` is an edge to ``pkg.mod`` alone."""
    mods = {}
    for p in sorted((root / package).rglob("*.py")):
        parts = list(p.relative_to(root).with_suffix("").parts)
        mods[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    graph = {}
    for name, path in mods.items():
        tree = ast.parse(path.read_text())
        skip = set() if typing_only else _type_checking_nodes(tree)
        here = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        targets = set()
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            if isinstance(node, ast.Import):
                targets |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = ".".join(here[: len(here) - node.level + 1] + [node.module or ""]).strip(".")
                mod = base if node.level else node.module
                targets |= {mod} | {f"{mod}.{a.name}" for a in node.names if f"{mod}.{a.name}" in mods}
        graph[name] = set()
        for t in targets:
            while t and t not in mods:
                t = t.rpartition(".")[0]
            if t and t != name:
                graph[name].add(t)
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph`` (its modules in order, the first repeated at the end), or None."""
    state, stack = {}, []

    def visit(v):
        state[v] = "open"
        stack.append(v)
        for w in sorted(graph[v]):
            if state.get(w) == "open":
                return stack[stack.index(w) :] + [w]
            if w not in state and (found := visit(w)):
                return found
        state[v] = "done"
        stack.pop()
        return None

    for v in sorted(graph):
        if v not in state and (found := visit(v)):
            return found
    return None


#: The import edges that exist for annotations only (under ``if TYPE_CHECKING:``) and would close a circle if they
#: ran: the bottom of the scene names the validated :class:`~study.scene.schema.Scene` in its signatures.
TYPING_ONLY_EDGES = {
    ("study.scene.room", "study.scene.schema"),  # room_mesh(scene: Scene)
    ("study.scene.environment", "study.scene.schema"),  # geometry(scene: Scene), env_key(scene: Scene)
}


def test_study_import_graph_is_acyclic():
    """No import cycle among study's modules, counting imports inside functions and imports through a package's
    ``__init__`` (``from study.scene import placement``); TYPE_CHECKING blocks aside: import-linter's contracts
    see only the packages' siblings and the top-level graph."""
    graph = import_graph(ROOT, "study")
    assert len(graph) > 80 and "study.methods.base" in graph["study.methods.classical"]
    assert find_cycle(graph) is None, " → ".join(find_cycle(graph))


def test_only_the_stated_typing_edges_point_back():
    """With the ``if TYPE_CHECKING:`` imports counted too, every cycle runs through one of
    :data:`TYPING_ONLY_EDGES`, and each of those is still there (the list says what exists)."""
    graph = import_graph(ROOT, "study", typing_only=True)
    assert all(b in graph[a] for a, b in TYPING_ONLY_EDGES)
    for a, b in TYPING_ONLY_EDGES:
        graph[a].discard(b)
    assert find_cycle(graph) is None, " → ".join(find_cycle(graph))


def test_the_scene_circle_is_found(tmp_path):
    """The circle the scene package had (data importing the machinery that places it, through the package's
    ``__init__``), rebuilt in a toy package, is a cycle to :func:`find_cycle`."""
    pkg = tmp_path / "toy"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from toy.schema import Scene\n")
    (pkg / "schema.py").write_text(
        "class Scene:\n    def place(self):\n        from toy.autoplace import f\n"
    )
    (pkg / "autoplace.py").write_text("from toy import placement\n\ndef f():\n    pass\n")
    (pkg / "placement.py").write_text("")
    assert find_cycle(import_graph(tmp_path, "toy")) == ["toy", "toy.schema", "toy.autoplace", "toy"]
    (pkg / "autoplace.py").write_text("import toy.placement as placement\n")
    assert find_cycle(import_graph(tmp_path, "toy")) is None


def test_a_planted_cycle_is_found(tmp_path):
    """The same check on a toy package: a cycle through a function-level import is found; one through an
    ``if TYPE_CHECKING:`` import is not."""
    pkg = tmp_path / "toy"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from toy.sub import b\n")
    (pkg / "sub" / "b.py").write_text("def f():\n    from .. import c\n")
    (pkg / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import toy.a\n")
    graph = import_graph(tmp_path, "toy")
    assert graph["toy.a"] == {"toy.sub", "toy.sub.b"} and graph["toy.sub.b"] == {"toy", "toy.c"}
    assert graph["toy.c"] == set()
    assert find_cycle(graph) is None
    (pkg / "c.py").write_text("def g():\n    import toy.a\n")
    assert find_cycle(import_graph(tmp_path, "toy")) == ["toy.a", "toy.sub.b", "toy.c", "toy.a"]


def test_no_module_is_over_460_lines():
    long = {
        str(p.relative_to(ROOT)): n
        for p in (ROOT / "study").rglob("*.py")
        if (n := len(p.read_text().splitlines())) > MAX_LINES
    }
    assert not long, f"split these modules: {long}"


def test_ruff_lint_and_format_pass():
    """House style by a tool: `ruff check` and `ruff format --check` (settings in pyproject.toml) on the repository."""
    import subprocess
    import sys

    for args in (["check", "."], ["format", "--check", "."]):
        proc = subprocess.run([sys.executable, "-m", "ruff", *args], cwd=ROOT, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]


def test_ruff_catches_a_long_line(tmp_path):
    """The same settings flag a 130-character line (the check above can fail)."""
    import subprocess
    import sys

    bad = tmp_path / "bad.py"
    bad.write_text("x = " + repr("a" * 124) + "\n")
    proc = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "--config", str(ROOT / "pyproject.toml"), str(bad)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 1 and "E501" in proc.stdout


def test_every_package_says_what_it_owns():
    for init in (ROOT / "study").rglob("__init__.py"):
        doc = init.read_text().lstrip()
        assert doc.startswith('"""') and len(doc.split('"""')[1].split()) >= 8, f"{init}: no docstring"


def test_map_of_the_house_is_current():
    """docs/architecture.md's 'Where things are' is what scripts/house.py makes from the docstrings today."""
    import runpy

    house = runpy.run_path(str(ROOT / "scripts" / "house.py"))
    text = (ROOT / "docs" / "architecture.md").read_text()
    assert house["render"](text) == text, (
        "run `python scripts/house.py` to regenerate docs/architecture.md's map"
    )


def test_readme_is_at_most_8_kb():
    """The README leads with the finding and links to docs/ for the rest; it stays short."""
    size = len((ROOT / "README.md").read_bytes())
    assert size <= 8 * 1024, f"README.md is {size} bytes; move detail into docs/"


def test_readme_commands_and_links_hold():
    """The README's two commands are there as written, and every file it links to or shows exists."""
    import re

    readme = (ROOT / "README.md").read_text()
    for cmd in (
        "bash scripts/reproduce.sh",
        "bash scripts/test.sh",
        "PYTHONPATH=. .venv/bin/python scripts/headline.py",
    ):
        assert f"\n    {cmd}\n" in readme, f"README.md: `{cmd}` is not a command block of its own"
    targets = re.findall(r"\]\(([^)#]+)\)", readme)  # Markdown links and images
    assert "docs/images/fig5-case.png" in targets
    missing = [t for t in targets if "://" not in t and not (ROOT / t).exists()]
    assert not missing, f"README.md links to missing files: {missing}"


#: Names several modules define on purpose: each method's Params model, and CLI commands named after the function
#: they call (``study check`` → budget and check, ``study animate`` → animation.animate, ``main``).
SHARED_NAMES = {"Params", "check", "animate", "main"}


def public_names(root: Path) -> dict[str, list[str]]:
    """name → the modules of ``root/study`` that define it at their top level: public functions, classes and
    UPPER_CASE constants (``X = …``, ``X: T = …``, ``X, Y = …``)."""
    import collections

    defs = collections.defaultdict(list)
    for p in sorted((root / "study").rglob("*.py")):
        for n in ast.parse(p.read_text()).body:
            names = [n.name] if isinstance(n, ast.FunctionDef | ast.ClassDef) else []
            targets = (
                n.targets if isinstance(n, ast.Assign) else [n.target] if isinstance(n, ast.AnnAssign) else []
            )
            for tg in targets:
                names += [
                    e.id for e in (tg.elts if isinstance(tg, ast.Tuple) else [tg]) if isinstance(e, ast.Name)
                ]
            for name in names:
                if not name.startswith("_") and (
                    name.isupper() or isinstance(n, ast.FunctionDef | ast.ClassDef)
                ):
                    defs[name].append(str(p.relative_to(root)))
    return defs


def twice(root: Path) -> dict[str, list[str]]:
    return {k: v for k, v in public_names(root).items() if len(v) > 1 and k not in SHARED_NAMES}


def test_one_meaning_per_name():
    """No public top-level function, class or UPPER_CASE constant is defined in two of study's modules (a reader
    who meets ``load_scene``, ``WRONG`` or ``COLUMNS`` should find one thing), except :data:`SHARED_NAMES`."""
    assert not twice(ROOT), twice(ROOT)


#: Modules where ``alpha`` is not GGX roughness, and why (to be renamed by the module's owner).
ALPHA_ELSEWHERE = {
    "study/stats/compare.py": "the significance level of its tests (scipy's name); the report's is SIGNIFICANCE",
    "study/stats/power.py": "the significance level of its tests (scipy's name); the report's is SIGNIFICANCE",
}


def alpha_outside_roughness(root: Path) -> dict[str, list[str]]:
    """module → its identifiers (names, arguments, attributes, definitions; keywords of outside libraries'
    calls, like matplotlib's ``alpha=``, and strings aside) that say alpha, where the module does not speak of
    roughness (no "GGX", "rough" or "glossy" in it), and every UPPER_CASE ALPHA."""
    import re

    word = re.compile(r"(?i)(^|_)alpha($|_)")
    out = {}
    for p in sorted((root / "study").rglob("*.py")):
        text = p.read_text()
        rough = re.search(r"(?i)ggx|rough|glossy", text) is not None
        found = set()
        for n in ast.walk(ast.parse(text)):
            for name in (
                [n.id] if isinstance(n, ast.Name) else
                [n.arg] if isinstance(n, ast.arg) else
                [n.attr] if isinstance(n, ast.Attribute) else
                [n.name] if isinstance(n, ast.FunctionDef | ast.ClassDef) else []
            ):  # fmt: skip
                if word.search(name) and (name.isupper() or not rough):
                    found.add(name)
        rel = str(p.relative_to(root))
        if found and rel not in ALPHA_ELSEWHERE:
            out[rel] = sorted(found)
    return out


def test_alpha_means_roughness():
    """ "alpha" is GGX roughness (``object.alpha``) and nothing else: no ALPHA constant (significance levels are
    ``SIGNIFICANCE``, an overlay's opacity ``OPACITY``), and no alpha in a module that does not deal with
    roughness, except :data:`ALPHA_ELSEWHERE`."""
    assert not alpha_outside_roughness(ROOT), alpha_outside_roughness(ROOT)
    assert all((ROOT / m).is_file() for m in ALPHA_ELSEWHERE)


def override_gaps(root: Path, package: str = "study/methods") -> list[str]:
    """Methods of classes in ``root/package`` that override a method of a base class (found by name among the
    package's classes) and drop one of its type hints (an argument's or the return's) or rename its arguments."""
    classes = {}
    for p in sorted((root / package).rglob("*.py")):
        for n in ast.parse(p.read_text()).body:
            if isinstance(n, ast.ClassDef):
                classes[n.name] = (p, n)

    def bases(node):
        for b in node.bases:
            name = b.id if isinstance(b, ast.Name) else getattr(b, "attr", None)
            if name in classes:
                yield classes[name][1]
                yield from bases(classes[name][1])

    hints = lambda f: {
        a.arg: ast.unparse(a.annotation) for a in f.args.args + f.args.kwonlyargs if a.annotation
    }  # noqa: E731
    gaps = []
    for p, node in classes.values():
        for f in (x for x in node.body if isinstance(x, ast.FunctionDef)):
            base = next(
                (
                    g
                    for b in bases(node)
                    for g in b.body
                    if isinstance(g, ast.FunctionDef) and g.name == f.name
                ),
                None,
            )
            if base is None:
                continue
            lost = [f"{a}: {h}" for a, h in hints(base).items() if hints(f).get(a) != h]
            if base.returns is not None and (
                f.returns is None or ast.unparse(f.returns) != ast.unparse(base.returns)
            ):
                lost.append(f"-> {ast.unparse(base.returns)}")
            names, base_names = [a.arg for a in f.args.args], [a.arg for a in base.args.args]
            if names[: len(base_names)] != base_names:
                lost.append(f"arguments {names} for {base_names}")
            if lost:
                gaps.append(f"{p.relative_to(root)}:{f.lineno} {node.name}.{f.name}: {', '.join(lost)}")
    return gaps


def test_method_overrides_keep_their_hints_and_names():
    """Every override of a method's contract (``localize``, ``search``, ``point``, ``sees_origin``, …) keeps the
    base's type hints and argument names: the captured views are ``env: Captured`` everywhere."""
    assert not override_gaps(ROOT), override_gaps(ROOT)
    named = {
        n.arg
        for p in (ROOT / "study").rglob("*.py")
        for n in ast.walk(ast.parse(p.read_text()))
        if isinstance(n, ast.arg) and n.annotation is not None and ast.unparse(n.annotation) == "Captured"
    }
    assert named == {"env"}, named


MAX_FUNCTION_LINES = 80
#: The functions longer than :data:`MAX_FUNCTION_LINES` (module::function → its length today, which it may not
#: exceed): pipelines read top to bottom, one stage after another, that nobody has split yet.
LONG_FUNCTIONS = {
    "study/bench/run.py::run_bench": 145,  # + the exact query priced after every method (CUDA)
    "study/caustics/figure.py::_fig8_files": 105,
    "study/harness/runner.py::run_cases": 92,
    "study/outputs/animation.py::_animate": 87,
    "study/methods/search.py::first_entry": 126,
    "study/outputs/figures.py::image_grid": 112,
    "study/outputs/figures.py::_figure": 90,
    "study/scene/obj.py::read_obj": 124,
    "study/scene/sources/mitsuba.py::build": 81,
}


def long_functions(root: Path) -> dict[str, int]:
    """module::function → its lines (``def`` to its last line), for every function of ``root/study`` over
    :data:`MAX_FUNCTION_LINES`."""
    return {
        f"{p.relative_to(root)}::{n.name}": n.end_lineno - n.lineno + 1
        for p in sorted((root / "study").rglob("*.py"))
        for n in ast.walk(ast.parse(p.read_text()))
        if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)
        and n.end_lineno - n.lineno + 1 > MAX_FUNCTION_LINES
    }


def test_functions_are_at_most_80_lines():
    """No function over 80 lines but the named exceptions, none of which grows; an exception that is gone or
    shorter is taken off the list."""
    found = long_functions(ROOT)
    grown = {k: n for k, n in found.items() if n > LONG_FUNCTIONS.get(k, MAX_FUNCTION_LINES)}
    assert not grown, f"split these functions (at most {MAX_FUNCTION_LINES} lines): {grown}"
    stale = {k: (n, found.get(k)) for k, n in LONG_FUNCTIONS.items() if found.get(k) != n}
    assert not stale, f"update LONG_FUNCTIONS (listed, now): {stale}"


def test_the_name_rules_catch_planted_errors(tmp_path):
    """The rules above on a toy tree: a constant defined twice, an ALPHA, alpha where nothing is rough, an override
    that drops a hint and renames the captured views, a 90-line function: each is found."""
    pkg = tmp_path / "study"
    pkg.mkdir()
    (pkg / "a.py").write_text("WRONG = 'x'\nALPHA = 0.05  # GGX\n")
    (pkg / "b.py").write_text("WRONG = 'y'\n\n\ndef blend(image, alpha):\n    return image * alpha\n")
    (pkg / "methods").mkdir()
    (pkg / "methods" / "m.py").write_text(
        "class Method:\n    def search(self, B: Backend, env: Captured) -> Found:\n        pass\n\n\n"
        "class Mine(Method):\n    def search(self, B, views):\n        pass\n"
    )
    (pkg / "c.py").write_text("def long():\n" + "    x = 1\n" * 89)
    assert twice(tmp_path) == {"WRONG": ["study/a.py", "study/b.py"]}
    assert alpha_outside_roughness(tmp_path) == {"study/a.py": ["ALPHA"], "study/b.py": ["alpha"]}
    gaps = override_gaps(tmp_path)
    assert len(gaps) == 1 and "env: Captured" in gaps[0] and "-> Found" in gaps[0] and "'views'" in gaps[0]
    assert long_functions(tmp_path) == {"study/c.py::long": 90}


def test_no_history_in_the_code():
    """Docstrings and comments say what the code does, not how it came to be: no "issue N" (history belongs in
    commits and issues)."""
    import re

    hits = [
        f"{p.relative_to(ROOT)}:{i}"
        for p in (ROOT / "study").rglob("*.py")
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if re.search(r"\bissues? \d+", line, re.I)
    ]
    assert not hits, hits
