"""The habits that keep the code easy to pick up, checked on the source itself (issue: a codebase a newcomer can
carry on): modules under 400 lines, functions under 80, few parameters; and the shape of its data: one name for
each class, few untyped dicts and few imports inside functions in the service; and packages that stand in floors,
none importing a package that imports it back.  The few exceptions are named here, each with its reason; a new one
fails this test until it is split or named."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("schemas", "tracer", "service")

MODULE_LINES, FUNCTION_LINES, PARAMETERS = 400, 80, 7
#: the service's ``dict[str, Any]`` (a record or a TypedDict says what a dict holds; an untyped one is for JSON
#: and CSV as they are read and written) and its import statements inside functions (an import belongs at the
#: top of its module, where it shows what the module depends on; one inside a function is for an optional
#: dependency, a command's start-up, or a cycle between two modules of one package, never one between packages,
#: which test_no_package_imports_its_importer forbids): at most these many
UNTYPED_DICTS, LOCAL_IMPORTS = 40, 57
#: functions allowed past FUNCTION_LINES or PARAMETERS, each until it is split (a name added here must say why
#: it cannot be yet)
LONG_FUNCTIONS = frozenset(
    {
        "tracer/proofs/sightlines.py:plain_triangles",  # the sightlines' test, its steps share many arrays
    }
)
MANY_PARAMETERS = frozenset(
    {  # the exact tests of rays against one kind of shape, each ray batch's columns apart
        "tracer/scene/shapes.py:triangle_t",
        "tracer/scene/shapes.py:sphere_t",
        "tracer/scene/shapes.py:plane_t",
        "tracer/exact/proxies.py:build_proxies",
    }
)


def _modules() -> list[Path]:
    return sorted(p for package in PACKAGES for p in (ROOT / package).rglob("*.py"))


def _functions(path: Path) -> list[tuple[str, ast.FunctionDef | ast.AsyncFunctionDef]]:
    tree = ast.parse(path.read_text(), str(path))
    where = path.relative_to(ROOT).as_posix()
    return [
        (f"{where}:{node.name}", node)
        for node in ast.walk(tree)
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
    ]


def _parameters(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = node.args
    given = [*a.posonlyargs, *a.args, *a.kwonlyargs]
    count = len(given) + (a.vararg is not None) + (a.kwarg is not None)
    return count - (1 if given and given[0].arg in ("self", "cls") else 0)


def _trees(package: str) -> list[tuple[Path, ast.Module]]:
    return [(p, ast.parse(p.read_text(), str(p))) for p in sorted((ROOT / package).rglob("*.py"))]


def _local_imports(tree: ast.Module) -> list[ast.Import | ast.ImportFrom]:
    """The import statements inside a function (one inside a nested function counted once)."""
    found: dict[int, ast.Import | ast.ImportFrom] = {}
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            found.update({id(n): n for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom))})
    return list(found.values())


def _untyped_dicts(tree: ast.Module) -> int:
    return sum(
        isinstance(node, ast.Subscript) and ast.unparse(node).replace(" ", "") == "dict[str,Any]"
        for node in ast.walk(tree)
    )


def test_the_gates_see_the_code():
    assert len(_modules()) > 50 and any(_functions(p) for p in _modules())


def test_no_module_is_over_its_lines():
    long = [
        (p.relative_to(ROOT).as_posix(), n) for p in _modules() if (n := len(p.read_text().splitlines())) > MODULE_LINES
    ]
    assert not long, f"modules over {MODULE_LINES} lines (split them by concept): {long}"


def test_no_function_is_over_its_lines():
    long = [
        (name, n)
        for p in _modules()
        for name, node in _functions(p)
        if (n := (node.end_lineno or node.lineno) - node.lineno + 1) > FUNCTION_LINES and name not in LONG_FUNCTIONS
    ]
    assert not long, f"functions over {FUNCTION_LINES} lines: {long}"


def test_no_function_takes_too_many_parameters():
    many = [
        (name, n)
        for p in _modules()
        for name, node in _functions(p)
        if (n := _parameters(node)) > PARAMETERS and name not in MANY_PARAMETERS
    ]
    assert not many, f"functions with more than {PARAMETERS} parameters (take a named record): {many}"


def test_no_class_name_is_defined_twice():
    where: dict[str, list[str]] = {}
    for package in PACKAGES:
        for path, tree in _trees(package):
            for node in ast.walk(tree):
                if isinstance(node, ast.ClassDef):
                    where.setdefault(node.name, []).append(path.relative_to(ROOT).as_posix())
    assert len(where) > 100
    twice = {name: paths for name, paths in where.items() if len(paths) > 1}
    assert not twice, f"classes of one name defined more than once (one name, one concept): {twice}"


def test_the_service_has_few_untyped_dicts():
    counted = {p.relative_to(ROOT).as_posix(): n for p, tree in _trees("service") if (n := _untyped_dicts(tree))}
    assert counted, "the count sees the service's dicts"
    total = sum(counted.values())
    most = sorted(counted.items(), key=lambda item: -item[1])[:5]
    assert total <= UNTYPED_DICTS, f"dict[str, Any] {total} times in service/ (at most {UNTYPED_DICTS}): {most}"


def test_the_service_imports_at_the_top():
    counted = {p.relative_to(ROOT).as_posix(): n for p, tree in _trees("service") if (n := len(_local_imports(tree)))}
    assert counted, "the count sees the service's imports inside functions"
    total = sum(counted.values())
    most = sorted(counted.items(), key=lambda item: -item[1])[:5]
    assert total <= LOCAL_IMPORTS, f"{total} imports inside functions in service/ (at most {LOCAL_IMPORTS}): {most}"


def _folder(module: str) -> list[str]:
    """The package a module stands in, as its folder's parts (a package's ``__init__`` stands in the package)."""
    parts = module.split(".")
    return parts if ROOT.joinpath(*parts).is_dir() else parts[:-1]


def _module(name: str) -> str | None:
    """``name`` as a module of this checkout (a file or a package), or None (a name inside a module)."""
    path = ROOT.joinpath(*name.split("."))
    return name if path.with_suffix(".py").is_file() or (path / "__init__.py").is_file() else None


def _imported(module: str, node: ast.Import | ast.ImportFrom) -> list[str]:
    """The modules of this checkout that one import statement of ``module`` loads."""
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names]
    else:
        base = _folder(module)[: len(_folder(module)) - node.level + 1] if node.level else []
        source = ".".join([*base, *([node.module] if node.module else [])])
        names = [_module(f"{source}.{alias.name}") or source for alias in node.names]
    return [found for name in names if name.split(".")[0] in PACKAGES and (found := _module(name))]


def _package_imports() -> dict[tuple[str, str], set[str]]:
    """Sibling package → sibling package (two folders in one folder, or two of schemas, tracer and service): the
    imports of a module under the first of a module under the second, function-local ones counted too."""
    edges: dict[tuple[str, str], set[str]] = {}
    for package in PACKAGES:
        for path, tree in _trees(package):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
            for node in ast.walk(tree):
                if isinstance(node, (ast.Import, ast.ImportFrom)):
                    for target in _imported(module, node):
                        a, b = _folder(module), _folder(target)
                        common = next((i for i, (x, y) in enumerate(zip(a, b)) if x != y), min(len(a), len(b)))
                        if len(a) > common and len(b) > common:
                            ends = (".".join(a[: common + 1]), ".".join(b[: common + 1]))
                            edges.setdefault(ends, set()).add(f"{module} -> {target}")
    return edges


def _circles(edges: dict[tuple[str, str], set[str]]) -> list[list[str]]:
    """The packages that import each other, round a loop however long (the strongly connected parts)."""
    after: dict[str, set[str]] = {}
    for a, b in edges:
        after.setdefault(a, set()).add(b)

    def reach(start: str) -> set[str]:
        seen, todo = set(), [start]
        while todo:
            for nxt in after.get(todo.pop(), ()):
                if nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        return seen

    reached = {p: reach(p) for p in after}
    circles = {frozenset({p, *(q for q in reached[p] if p in reached.get(q, ()))}) for p in after if p in reached[p]}
    return sorted(sorted(circle) for circle in circles)


def test_the_graph_sees_the_imports():
    edges = _package_imports()
    assert ("service.cli", "service.classgrade") in edges and ("service", "tracer") in edges
    assert _circles({("a", "b"): set(), ("b", "c"): set(), ("c", "a"): set(), ("c", "d"): set()}) == [["a", "b", "c"]]


def test_no_package_imports_its_importer():
    """Packages stand in floors: a package imports only packages that do not import it back, however far round
    (function-local imports counted too: a cycle dodged at run time is a cycle still)."""
    edges = _package_imports()
    ties = {
        " <-> ".join(circle): sorted(m for (a, b), ms in edges.items() if a in circle and b in circle for m in ms)
        for circle in _circles(edges)
    }
    assert not ties, f"packages that import each other (move what both need below them): {ties}"
