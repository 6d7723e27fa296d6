"""The Rust sources depend on each other in layers (issue 21): no two files
import each other, and no longer cycle either, as scripts/check_imports.py
sees them (use paths, written-out crate paths through re-exports, impl blocks
of a type defined in another file). A self-test on a small tree with a
cycle shows that the check can fail."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "check_imports.py"


def check(src):
    return subprocess.run([sys.executable, str(SCRIPT), str(src)], capture_output=True, text=True)


def test_the_sources_have_no_import_cycle():
    r = check(ROOT / "src")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "no cycles" in r.stdout


def write(tree, files):
    for name, text in files.items():
        path = tree / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def test_a_pair_that_imports_each_other_is_found(tmp_path):
    write(
        tmp_path,
        {
            "lib.rs": "pub mod a;\npub mod b;\n",
            "a.rs": "use crate::b::Beta;\npub struct Alpha;\n",
            "b/mod.rs": "mod inner;\npub use inner::Beta;\n",
            "b/inner.rs": "pub struct Beta;\nfn f() -> usize { crate::a::helper() }\n",
        },
    )
    (tmp_path / "a.rs").write_text("use crate::b::Beta;\npub struct Alpha;\npub fn helper() -> usize { 1 }\n")
    r = check(tmp_path)
    assert r.returncode == 1, r.stdout
    assert "cycle: " in r.stdout and "a.rs" in r.stdout and "inner.rs" in r.stdout


def test_methods_added_to_another_files_type_count_as_a_dependency(tmp_path):
    write(
        tmp_path,
        {
            "lib.rs": "mod sim;\nmod steps;\n",
            "sim.rs": "use crate::steps::Control;\npub struct Simulator { c: Control }\n",
            "steps.rs": "pub enum Control { Fixed }\nimpl Simulator {\n    fn step(&self) {}\n}\n",
        },
    )
    r = check(tmp_path)
    assert r.returncode == 1, r.stdout
    assert "steps.rs -> " in r.stdout and "sim.rs -> " in r.stdout
