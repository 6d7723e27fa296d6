"""The FMU documents itself (FMI 2.0 §2.3): every ``.fmu`` package_fmu writes carries
``documentation/index.html`` and the icon ``model.png``, generated from the model it runs.

Checked for the reference FMU, the motor FMU (models/reference_rrpr_motor.toml, built once per
process by motor_fmus.py) and the KUKA iiwa URDF FMU (urdf_fmus.py):

* both files are in the archive, and fmpy.extract puts the page at
  ``<unzipdir>/documentation/index.html`` with the icon it shows at ``../model.png``;
* the page is well-formed HTML5 (html.parser and a tag-balance checker: no unclosed or stray
  tags, unique ids, in-page links that resolve, nothing loaded from the web) and names the
  modelDescription's GUID and modelName;
* it lists every variable of modelDescription.xml (read by fmpy) in the group of its
  causality, with its value reference, unit, range, start value and description;
* its joint table matches the model: joint kind, drive and friction contact against what
  the modelDescription's variables imply (q[i] in rad or m; k[i] or tau_m[i]; d_A[i] or
  slider_a[i]), and the known chains: the reference RRPR arm, motor drives on joints 1 and 3
  of the motor model, the iiwa's URDF joint names;
* the repository files it refers to (docs/*.md) exist;
* ``model.png`` is a valid PNG (chunk CRCs and zlib stream checked with Python's zlib), decodes
  with matplotlib to at least 64x64 RGBA, and shows the chain in several colours, among them
  those of the drives (rigid grey, flexible blue, motor orange).
"""

from __future__ import annotations

import functools
import io
import re
import struct
import zipfile
import zlib
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from helpers import ROOT, require_fmu
from motor_fmus import require_motor_fmu
from urdf_fmus import IIWA_JOINTS, require_iiwa_fmu

# CI's full run only (scripts/test.sh --quick leaves it out): the motor and iiwa FMUs built
pytestmark = pytest.mark.full

DOC = "documentation/index.html"
ICON = "model.png"
# The drive colours of src/fmi/description/documentation.rs (DRIVE_COLOURS), RGB.
DRIVE_COLOURS = {"rigid": (0x78, 0x80, 0x88), "flexible": (0x1F, 0x6F, 0xC0), "motor": (0xE0, 0x6C, 0x10)}

# The known chains: (kind, drive, friction contact) per joint, and URDF joint names.
REFERENCE_CHAIN = [
    ("revolute", "flexible", "bearings"),
    ("revolute", "rigid", "none"),
    ("prismatic", "flexible", "slider"),
    ("revolute", "rigid", "none"),
]
MOTOR_CHAIN = [
    ("revolute", "motor", "bearings"),
    ("revolute", "rigid", "none"),
    ("prismatic", "motor", "slider"),
    ("revolute", "rigid", "none"),
]
IIWA_CHAIN = [
    ("revolute", "flexible" if i in (1, 2, 4) else "rigid", "bearings" if i in (1, 2, 4) else "none")
    for i in range(1, 8)
]

FMUS = {
    "reference": (require_fmu, REFERENCE_CHAIN, None),
    "motor": (require_motor_fmu, MOTOR_CHAIN, None),
    "iiwa": (require_iiwa_fmu, IIWA_CHAIN, IIWA_JOINTS),
}


# ---------------------------------------------------------------------------
# the page, parsed

VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}


class Page(HTMLParser):
    """The page's structure: tag balance problems, ids, links, table rows by table and
    section, the text of the sections."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.problems: list[str] = []
        self.stack: list[tuple[str, dict]] = []
        self.doctype = None
        self.ids: list[str] = []
        self.links: list[tuple[str, str]] = []  # (attribute, value)
        self.tags: dict[str, int] = {}
        self.rows: list[tuple[str, str, str, list[str]]] = []  # (table id, table class, section id, cells)
        self._row = None
        self._cell = None
        self.text: list[str] = []

    def handle_decl(self, decl):
        self.doctype = decl

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags[tag] = self.tags.get(tag, 0) + 1
        if "id" in a:
            self.ids.append(a["id"])
        for key in ("href", "src"):
            if key in a:
                self.links.append((key, a[key]))
        if tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = []
        if tag not in VOID:
            self.stack.append((tag, a))

    def handle_startendtag(self, tag, attrs):
        self.handle_starttag(tag, attrs)
        if tag not in VOID:
            self.problems.append(f"self-closing non-void <{tag}/>")
            self.stack.pop()

    def handle_endtag(self, tag):
        if tag in VOID:
            self.problems.append(f"end tag of void element </{tag}>")
            return
        if not self.stack or self.stack[-1][0] != tag:
            open_tags = [t for t, _ in self.stack]
            self.problems.append(f"</{tag}> closes {open_tags[-1:] or 'nothing'} (open: {open_tags})")
            return
        self.stack.pop()
        if tag in ("td", "th") and self._row is not None:
            self._row.append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "tr" and self._row is not None:
            table = next((a for t, a in reversed(self.stack) if t == "table"), {})
            section = next((a.get("id", "") for t, a in reversed(self.stack) if t == "section"), "")
            self.rows.append((table.get("id", ""), table.get("class", ""), section, self._row))
            self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)
        if not self.stack or self.stack[-1][0] not in ("style", "script"):
            self.text.append(data)

    def close(self):
        super().close()
        if self.stack:
            self.problems.append(f"unclosed at the end: {[t for t, _ in self.stack]}")


@functools.cache
def archive(which: str):
    """(fmu path, {name: bytes} of the documentation files, ModelDescription)."""
    from fmpy import read_model_description

    path = FMUS[which][0]()
    with zipfile.ZipFile(path) as z:
        names = set(z.namelist())
        files = {n: z.read(n) for n in (DOC, ICON) if n in names}
    return path, files, read_model_description(str(path))


def page(which: str) -> Page:
    _, files, _ = archive(which)
    assert DOC in files, f"{which}: no {DOC} in the FMU"
    p = Page()
    p.feed(files[DOC].decode("utf-8"))
    p.close()
    return p


def fmus():
    return pytest.mark.parametrize("which", list(FMUS))


# ---------------------------------------------------------------------------
# the archive


@fmus()
def test_archive_carries_documentation_and_icon(which):
    _, files, _ = archive(which)
    assert set(files) == {DOC, ICON}


def test_fmpy_extract_gives_the_documentation_path(tmp_path):
    """How a user opens it from fmpy: fmpy.extract, then <unzipdir>/documentation/index.html,
    which shows the icon ../model.png."""
    import fmpy

    path, files, _ = archive("reference")
    unzipdir = Path(fmpy.extract(str(path), unzipdir=tmp_path / "fmu"))
    index = unzipdir / "documentation" / "index.html"
    assert index.is_file() and index.read_bytes() == files[DOC]
    sources = [v for k, v in page("reference").links if k == "src"]
    assert sources == ["../model.png"]
    assert (index.parent / sources[0]).resolve() == (unzipdir / "model.png").resolve()
    assert (unzipdir / "model.png").read_bytes() == files[ICON]


# ---------------------------------------------------------------------------
# the page


@fmus()
def test_page_is_well_formed_html5(which):
    _, files, md = archive(which)
    text = files[DOC].decode("utf-8")
    assert text.startswith('<!DOCTYPE html>\n<html lang="en">')
    p = page(which)
    assert p.doctype == "DOCTYPE html"
    assert not p.problems, p.problems
    for tag in ("html", "head", "body", "title", "main"):
        assert p.tags.get(tag) == 1, f"<{tag}> {p.tags.get(tag, 0)} times"
    assert '<meta charset="utf-8">' in text
    assert len(p.ids) == len(set(p.ids)), "duplicate ids"
    # Nothing from the web, no script: the style is inline, links stay in the page or the archive.
    assert "script" not in p.tags and "link" not in p.tags
    for key, target in p.links:
        if target.startswith("#"):
            assert target[1:] in p.ids, f"{key}={target} points nowhere"
        else:
            assert "//" not in target and ":" not in target, f"{key}={target} leaves the FMU"
    # Every `<` opens markup and every `&` a character reference: the descriptions' <, >, &
    # and ' were escaped (test_page_lists_every_variable reads them back).
    assert not re.findall(r"<(?![a-zA-Z/!])", text)
    assert not re.findall(r"&(?!#\d+;|#x[0-9a-fA-F]+;|[a-zA-Z]+;)", text)
    body = " ".join("".join(p.text).split())
    assert md.guid in body and md.modelName in body
    assert f"{md.modelName} — StickSlipManipulator FMU" in body


@fmus()
def test_page_lists_every_variable(which):
    _, _, md = archive(which)
    rows = {r[3][0]: (r[2], r[3]) for r in page(which).rows if r[1] == "variables" and r[3][0] != "name"}
    assert sorted(rows) == sorted(v.name for v in md.modelVariables)
    group = {"input": "inputs", "output": "outputs"}
    for v in md.modelVariables:
        section, (_name, vr, ty, unit, range_, start, variability, description) = rows[v.name]
        where = f"{which}: {v.name}"
        if v.causality in group:
            assert section == group[v.causality], where
        else:
            assert section in ("parameters", "start-values", "settings"), where
            assert v.causality == "parameter", where
        assert int(vr) == v.valueReference, where
        assert ty == v.type, where
        assert unit == (v.unit or ""), where
        assert description == " ".join(v.description.split()), where
        assert variability == v.variability, where
        if v.start is None:
            assert start == "", where
        elif v.type == "Boolean":
            assert start == str(v.start).lower(), where
        else:
            assert float(start) == float(v.start), where
        if v.min is not None and v.max is not None:
            lo, hi = re.fullmatch(r"\[(\S+), (\S+)\]", range_).groups()
            assert (float(lo), float(hi)) == (float(v.min), float(v.max)), where
        else:
            assert v.min is None and v.max is None and range_ == "", where


def _joint_rows(which):
    rows = [r[3] for r in page(which).rows if r[0] == "joints"]
    header, body = rows[0], rows[1:]
    return [dict(zip(header, cells, strict=True)) for cells in body]


@fmus()
def test_joint_table_matches_the_model(which):
    _, _, md = archive(which)
    _, chain, urdf_names = FMUS[which]
    joints = _joint_rows(which)
    assert [(j["kind"], j["drive"], j["friction contact"]) for j in joints] == chain
    assert [int(j["joint"]) for j in joints] == list(range(1, len(chain) + 1))
    if urdf_names is None:
        assert all("URDF joint" not in j for j in joints)
    else:
        assert [j["URDF joint"] for j in joints] == urdf_names
    # Against what the modelDescription's variables imply.
    var = {v.name: v for v in md.modelVariables}
    for i, j in enumerate(joints, start=1):
        kind = {"rad": "revolute", "m": "prismatic"}[var[f"q[{i}]"].unit]
        drive = "motor" if f"tau_m[{i}]" in var else "flexible" if f"k[{i}]" in var else "rigid"
        contact = "bearings" if f"d_A[{i}]" in var else "slider" if f"mu_k[{i}]" in var else "none"
        assert (j["kind"], j["drive"], j["friction contact"]) == (kind, drive, contact), f"{which} joint {i}"
        assert float(j["link mass"].removesuffix(" kg")) == float(var[f"m[{i}]"].start)


def test_motor_drives_are_documented():
    p = page("motor")
    section = " ".join("".join(p.text).split())
    for i in (1, 3):
        assert f"joint {i}: in tau_m[{i}]; out theta_m[{i}]" in section
        assert f"motor encoder theta_m[{i}] / gear_ratio[{i}]" in section
    assert "fmi2SetRealInputDerivatives" in section
    assert "no motor drives" in " ".join("".join(page("reference").text).split())


@fmus()
def test_coupling_and_references(which):
    body = " ".join("".join(page(which).text).split())
    for phrase in (
        "fmi2SetRealInputDerivatives",
        "fmi2Discard",
        "fmi2LastSuccessfulTime",
        "fmi2GetFMUstate",
        "fmi2SerializeFMUstate",
        "docs/motor_drives.md",
        "docs/control.md",
        "README.md",
    ):
        assert phrase in body, phrase
    named = set(re.findall(r"\bdocs/[\w.-]+\.md\b", body))
    assert len(named) >= 5
    for f in sorted(named):
        assert (ROOT / f).is_file(), f"the page names {f}, which the repository does not have"


# ---------------------------------------------------------------------------
# the icon


def _png_chunks(data: bytes):
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, out = 8, []
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])
        assert crc == zlib.crc32(kind + body), f"CRC of {kind!r}"
        out.append((kind, body))
        pos += 12 + length
    return out


@fmus()
def test_icon_is_a_valid_png_of_the_chain(which):
    import matplotlib.image as mpimg

    _, files, _ = archive(which)
    data = files[ICON]
    chunks = _png_chunks(data)
    assert chunks[0][0] == b"IHDR" and chunks[-1][0] == b"IEND"
    width, height, depth, colour, compression, filtering, interlace = struct.unpack(">IIBBBBB", chunks[0][1])
    assert (depth, colour, compression, filtering, interlace) == (8, 6, 0, 0, 0)
    raw = zlib.decompress(b"".join(body for kind, body in chunks if kind == b"IDAT"))
    assert len(raw) == height * (1 + 4 * width)
    assert all(raw[y * (1 + 4 * width)] <= 4 for y in range(height)), "filter types 0..4"

    image = mpimg.imread(io.BytesIO(data), format="png")
    assert image.shape == (height, width, 4) and min(width, height) >= 64
    rgba = np.round(np.asarray(image) * 255).astype(np.uint8)
    opaque = rgba[rgba[..., 3] == 255][:, :3]
    colours = {tuple(int(x) for x in c) for c in np.unique(opaque, axis=0)}
    assert len(colours) >= 8, f"{len(colours)} colours: blank?"
    drives = {d for _, d, _ in FMUS[which][1]}
    for drive, colour in DRIVE_COLOURS.items():
        assert (colour in colours) == (drive in drives), f"{which}: {drive} colour"
    # Not one colour: the drawing covers a fair part of the background.
    _, counts = np.unique(opaque, axis=0, return_counts=True)
    assert 0.3 < counts.max() / len(opaque) < 0.97
