"""The Python package's modules import each other without a cycle (issue 35): every import,
at module level or inside a function, relative or absolute, is an edge of the graph, and no
module reaches itself through it. A self-test on a small package with a cycle shows that the
check can fail."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "python" / "stickslip"


def module_name(package: Path, path: Path) -> str:
    parts = [package.name, *path.relative_to(package).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(package: Path) -> dict:
    """module -> the package's modules it imports (a name imported from a package counts as
    its submodule when one of that name exists)."""
    modules = {module_name(package, p): p for p in package.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        is_package = path.name == "__init__.py"
        here = name.split(".") if is_package else name.split(".")[:-1]
        edges = set()
        for node in ast.walk(ast.parse(path.read_text())):
            targets = []
            if isinstance(node, ast.ImportFrom):
                base = here[: len(here) - node.level + 1] if node.level else []
                stem = ".".join(base + (node.module.split(".") if node.module else []))
                targets = [stem] + [f"{stem}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            edges |= {t for t in targets if t in modules and t != name}
        graph[name] = edges
    return graph


def cycles(graph: dict) -> list:
    """The strongly connected components of more than one module, by the Tarjan of
    scripts/check_imports.py (the Rust sources' check)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("check_imports", ROOT / "scripts" / "check_imports.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return [sorted(c) for c in module.strongly_connected(graph) if len(c) > 1]


def without_parents(graph: dict) -> dict:
    """A package's __init__ importing its own submodules is not a cycle through them."""
    return {v: {w for w in ws if not v.startswith(w + ".")} for v, ws in graph.items()}


def test_the_package_has_no_import_cycle():
    graph = without_parents(imports(PACKAGE))
    assert "stickslip.cluster" in graph["stickslip.fit.cli"]
    assert cycles(graph) == []


def test_a_cycle_through_a_function_level_import_is_found(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "cli.py").write_text("from .sub import cli as sub_cli\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "cli.py").write_text("def f():\n    from ..cli import helper\n")
    assert cycles(without_parents(imports(pkg))) == [["pkg.cli", "pkg.sub.cli"]]
