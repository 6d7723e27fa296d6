"""Every relative link and anchor of the documentation resolves, and the README stays short.

The Markdown files checked: those of the repository root (README.md), of docs/ (any
depth), examples/ and models/ (any depth) and modelDescription/. In each, every
relative link -- inline ``[text](path)``, ``[text](path#anchor)``, ``[text](#anchor)``,
images ``![alt](path)``, reference definitions ``[ref]: path`` and the ``src``/``href``
of HTML tags -- must name an existing file or directory (relative to the Markdown
file), and every ``#anchor`` into a Markdown file must be the anchor of one of its
headings, computed as GitHub does:

* the heading's rendered text (inline code keeps its text, emphasis markers, links and
  HTML tags keep only their text), lowercased;
* every character that is not a letter, a mark, a digit, ``_``, ``-`` or a space is
  dropped, and each space becomes ``-`` (so "a = b" gives ``a--b``);
* a heading whose anchor an earlier heading of the file already has gets ``-1``,
  the next ``-2``, and so on.

``id="…"`` and ``name="…"`` attributes of HTML elements are anchors too. Links inside
fenced code blocks and inline code are not links; external links (``http:``,
``https:``, ``mailto:``, any ``scheme:``) are not fetched.

The self-tests build a temporary tree with a broken link, a broken anchor and a broken
image, so that the checker is seen to fail where it must.
"""

from __future__ import annotations

import html
import re
import unicodedata
from pathlib import Path
from urllib.parse import unquote

ROOT = Path(__file__).resolve().parents[2]
README_MAX_LINES = 300

FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})")
ATX = re.compile(r"^ {0,3}(#{1,6})(?:[ \t]+(.*?))?(?:[ \t]+#+)?[ \t]*$")
CODE_SPAN = re.compile(r"(`+)(.+?)(?<!`)\1(?!`)", re.S)
# [text](target "title") and ![alt](target); the text may span lines and hold one
# level of nested brackets (e.g. `q[1]`, already blanked as code).
INLINE_LINK = re.compile(
    r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*(<[^>]*>|[^)\s]+)(?:\s+(?:\"[^\"]*\"|'[^']*'|\([^)]*\)))?\s*\)"
)
REF_DEF = re.compile(r"^ {0,3}\[[^\]]+\]:\s*(<[^>]*>|\S+)", re.M)
HTML_ATTR_LINK = re.compile(r"<[a-zA-Z][^>]*?\b(?:src|href)\s*=\s*(\"[^\"]*\"|'[^']*')", re.S)
HTML_ANCHOR = re.compile(r"<[a-zA-Z][^>]*?\b(?:id|name)\s*=\s*(\"[^\"]*\"|'[^']*')", re.S)
SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


def markdown_files(root: Path = ROOT) -> list[Path]:
    """The Markdown files whose links are checked."""
    files = sorted(root.glob("*.md"))
    for sub in ("docs", "examples", "models", "modelDescription"):
        if (root / sub).is_dir():
            files += sorted(p for p in (root / sub).rglob("*.md") if p.is_file())
    return files


def split_code(text: str) -> tuple[str, list[str]]:
    """The text with fenced code blocks blanked (line count kept), and the lines
    outside fences (for the headings)."""
    out, outside, fence = [], [], None
    for line in text.split("\n"):
        m = FENCE.match(line)
        if fence is None and m:
            fence = m.group(1)
            out.append("")
            continue
        if fence is not None:
            if (
                m
                and m.group(1)[0] == fence[0]
                and len(m.group(1)) >= len(fence)
                and not line.strip()[len(m.group(1)) :].strip()
            ):
                fence = None
            out.append("")
            continue
        out.append(line)
        outside.append(line)
    return "\n".join(out), outside


def blank_code_spans(text: str) -> str:
    return CODE_SPAN.sub(lambda m: " " * len(m.group(0)), text)


def heading_text(raw: str) -> str:
    """The rendered text of a heading's Markdown source."""
    t = CODE_SPAN.sub(lambda m: m.group(2).strip(), raw)
    t = re.sub(r"!?\[((?:[^\[\]]|\[[^\[\]]*\])*)\]\([^)]*\)", r"\1", t)  # links, images: their text
    t = re.sub(r"<[^>]+>", "", t)  # HTML tags
    t = re.sub(r"(?<!\\)(\*+|~~)", "", t)  # emphasis and strike-through markers
    t = re.sub(r"(?<![A-Za-z0-9\\])_+|(?<!\\)_+(?![A-Za-z0-9])", "", t)  # _emphasis_, not snake_case
    t = re.sub(r"\\(.)", r"\1", t)  # backslash escapes
    return html.unescape(t).strip()


def slug(text: str) -> str:
    """GitHub's anchor of a heading text (before the duplicate suffix)."""
    kept = []
    for ch in text.lower():
        if ch in " -_" or unicodedata.category(ch)[0] in "LMN":
            kept.append(ch)
    return "".join(kept).replace(" ", "-")


def anchors_of(path: Path) -> set[str]:
    """Every anchor a link may name in the Markdown file `path`."""
    text = path.read_text(encoding="utf-8")
    _, lines = split_code(text)
    seen: dict[str, int] = {}
    anchors: set[str] = set()
    for line in lines:
        m = ATX.match(line)
        if not m:
            continue
        base = slug(heading_text(m.group(2) or ""))
        anchor = base
        if base in seen:
            n = seen[base]
            while True:
                n += 1
                anchor = f"{base}-{n}"
                if anchor not in anchors:
                    break
            seen[base] = n
        else:
            seen[base] = 0
        anchors.add(anchor)
    for m in HTML_ANCHOR.finditer(blank_code_spans(split_code(text)[0])):
        anchors.add(m.group(1)[1:-1])
    return anchors


def links_of(path: Path) -> list[tuple[int, str]]:
    """(line number, target) of every link in the Markdown file `path`."""
    text, _ = split_code(path.read_text(encoding="utf-8"))
    text = blank_code_spans(text)
    found = []
    for pattern in (INLINE_LINK, REF_DEF, HTML_ATTR_LINK):
        for m in pattern.finditer(text):
            target = m.group(1)
            if target[:1] in "<\"'":
                target = target[1:-1]
            found.append((text.count("\n", 0, m.start(1)) + 1, target.strip()))
    return sorted(found)


def broken_links(files: list[Path], root: Path = ROOT) -> list[str]:
    """A message for each relative link or anchor of `files` that does not resolve."""
    problems = []
    cache: dict[Path, set[str]] = {}
    for md in files:
        where = md.relative_to(root) if md.is_relative_to(root) else md
        for line, target in links_of(md):
            if not target or SCHEME.match(target):
                continue
            path_part, _, anchor = target.partition("#")
            path_part = unquote(path_part.split("?", 1)[0])
            dest = md if not path_part else (md.parent / path_part)
            if path_part.startswith("/"):
                dest = root / path_part.lstrip("/")
            if not dest.exists():
                problems.append(f"{where}:{line}: `{target}`: no file {path_part}")
                continue
            if anchor and dest.is_file() and dest.suffix.lower() == ".md":
                dest = dest.resolve()
                if dest not in cache:
                    cache[dest] = anchors_of(dest)
                if unquote(anchor) not in cache[dest]:
                    problems.append(
                        f"{where}:{line}: `{target}`: no heading with anchor #{anchor} in {path_part or where}"
                    )
    return problems


# ---- the repository ------------------------------------------------------------------


def test_every_relative_link_and_anchor_resolves():
    files = markdown_files()
    assert ROOT / "README.md" in files and any(p.parent.name == "docs" for p in files)
    problems = broken_links(files)
    assert not problems, "broken links:\n" + "\n".join(problems)


def test_readme_is_at_most_300_lines():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").count("\n")
    assert lines <= README_MAX_LINES, f"README.md has {lines} lines, at most {README_MAX_LINES}"


def test_readme_links_every_docs_page():
    readme = {t.partition("#")[0] for _, t in links_of(ROOT / "README.md")}
    missing = [p.name for p in sorted((ROOT / "docs").glob("*.md")) if f"docs/{p.name}" not in readme]
    assert not missing, f"README.md links no docs page {missing}"


# ---- the checker itself --------------------------------------------------------------


def test_slugs_follow_githubs_rule():
    assert slug(heading_text("Parameter studies: `stickslip sweep`")) == "parameter-studies-stickslip-sweep"
    assert slug(heading_text("3. Across the parameter space")) == "3-across-the-parameter-space"
    assert (
        slug(heading_text("Variables (reference model; i = joint number, 1…n)"))
        == "variables-reference-model-i--joint-number-1n"
    )
    assert (
        slug(heading_text("Is a number converged? `--check-convergence`"))
        == "is-a-number-converged---check-convergence"
    )
    assert (
        slug(heading_text("(b) Hunting: integral action and a link-side encoder"))
        == "b-hunting-integral-action-and-a-link-side-encoder"
    )
    assert slug(heading_text("**Bold** and [a link](x.md) and <em>html</em>")) == "bold-and-a-link-and-html"
    assert slug(heading_text("snake_case_name and ε, μ₃")) == "snake_case_name-and-ε-μ₃"


def test_checker_fails_on_broken_links_and_anchors(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "figures").mkdir()
    (tmp_path / "docs" / "figures" / "a.png").write_bytes(b"")
    (tmp_path / "docs" / "page.md").write_text(
        '# Page\n\n## Same\n\n## Same\n\n### Odd: `code` & *stuff*\n\n<a id="custom"></a>\n', encoding="utf-8"
    )
    (tmp_path / "README.md").write_text(
        "# Top\n\n"
        "[ok](docs/page.md) [ok](docs/page.md#same) [ok](docs/page.md#same-1) [ok](docs/page.md#odd-code--stuff)\n"
        "[ok](docs/page.md#custom) [ok](#top) [ok](https://example.com/nothing#x) ![ok](docs/figures/a.png)\n"
        "[ok, a directory](docs/) `[not a link](nowhere.md)`\n\n"
        "```sh\n[not a link](nowhere.md)\n```\n\n"
        "[broken file](docs/missing.md)\n"
        "[broken anchor](docs/page.md#same-2)\n"
        "![broken image\nover two lines](docs/figures/missing.png)\n"
        "[broken self anchor](#nowhere)\n"
        '<img src="docs/figures/gone.svg">\n'
        "[ref]: docs/absent.md\n",
        encoding="utf-8",
    )
    problems = broken_links(markdown_files(tmp_path), tmp_path)
    text = "\n".join(problems)
    assert len(problems) == 6, text
    for needle in ("docs/missing.md", "#same-2", "docs/figures/missing.png", "#nowhere", "gone.svg", "docs/absent.md"):
        assert needle in text, f"{needle} not reported:\n{text}"
    assert text.startswith("README.md:11: `docs/missing.md`"), text  # line numbers point at the link


def test_checker_passes_a_clean_tree(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "a.md").write_text("# A\n\n[back](../README.md#readme-title)\n", encoding="utf-8")
    (tmp_path / "README.md").write_text("# README title\n\n[a](docs/a.md#a)\n", encoding="utf-8")
    assert broken_links(markdown_files(tmp_path), tmp_path) == []
