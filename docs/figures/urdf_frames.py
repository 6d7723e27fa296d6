#!/usr/bin/env python3
"""Draws docs/figures/urdf_frames.svg: the contact geometry of a URDF joint in its own frame
(docs/urdf.md). Run from anywhere: python docs/figures/urdf_frames.py (needs matplotlib)."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, Rectangle

OUT = Path(__file__).with_suffix(".svg")
plt.rcParams["svg.hashsalt"] = "urdf_frames"
plt.rcParams["font.size"] = 9

PARENT, CHILD, BEARING, AXIS = "#c9d6e8", "#f3d9b1", "#555555", "#2a6f2a"


def arrow(ax, p, q, color="k", lw=1.2, style="-|>", ms=10, **kw):
    ax.add_patch(FancyArrowPatch(p, q, arrowstyle=style, mutation_scale=ms, color=color, lw=lw, **kw))


def dim(ax, x, y0, y1, text, side=1):
    """A vertical dimension line at x from y0 to y1, labelled."""
    ax.add_patch(FancyArrowPatch((x, y0), (x, y1), arrowstyle="<|-|>", mutation_scale=8, color="k", lw=0.8))
    ax.text(x + 0.08 * side, (y0 + y1) / 2, text, ha="left" if side > 0 else "right", va="center")


def revolute(ax):
    ax.set_title("(a) revolute joint: bearings A, B (radial) and C (thrust)", loc="left", fontsize=10)
    # link i-1: the sleeve (two walls, a floor carrying the thrust bearing)
    for x0 in (-1.25, 0.55):
        ax.add_patch(Rectangle((x0, -1.55), 0.7, 2.45, fc=PARENT, ec="k", hatch="//", lw=0.8))
    ax.add_patch(Rectangle((-1.25, -1.95), 2.5, 0.4, fc=PARENT, ec="k", hatch="//", lw=0.8))
    ax.text(-1.3, -2.2, "link i−1 (URDF parent link): sleeve", ha="left", va="top")
    # link i: the pin, and its body above
    ax.add_patch(Rectangle((-0.45, -1.45), 0.9, 3.05, fc=CHILD, ec="k", lw=0.8))
    ax.add_patch(Rectangle((-1.05, 1.6), 2.1, 0.55, fc=CHILD, ec="k", lw=0.8))
    ax.text(1.15, 1.9, "link i (URDF child link): pin", ha="left", va="center")
    # the joint axis
    ax.plot([0, 0], [-2.05, 2.75], color=AXIS, lw=1.0, ls=(0, (6, 3)))
    arrow(ax, (0, 2.45), (0, 2.95), color=AXIS, lw=1.6)
    ax.text(0.1, 3.0, "joint axis a (URDF <axis>; the engine's z)", color=AXIS, ha="left", va="center")
    # joint frame origin O at the mating face (z = 1.6 here), x to the right
    oz = 1.6
    ax.plot(0, oz, "ko", ms=4)
    arrow(ax, (0, oz), (0.75, oz), lw=1.4)
    ax.text(0.78, oz - 0.08, "x", ha="left", va="top")
    ax.text(-0.12, oz + 0.1, "O", ha="right", va="bottom", fontweight="bold")
    # reference point P on the axis, bearings A below, B above
    pz, la, lb = 0.0, 1.0, 0.7
    ax.plot(0, pz, "o", color="tab:red", ms=5, zorder=5)
    ax.text(0.1, pz - 0.08, "P", color="tab:red", ha="left", va="top", fontweight="bold")
    for z, name in ((pz - la, "A"), (pz + lb, "B")):
        for x in (-0.5, 0.5):
            ax.add_patch(plt.Circle((x, z), 0.06, fc=BEARING, ec="k", lw=0.5, zorder=4))
        ax.text(-1.35, z, f"bearing {name}", ha="right", va="center")
    dim(ax, 1.45, pz - la, pz, "l_a", side=1)
    dim(ax, 1.45, pz, pz + lb, "l_b", side=1)
    for z in (pz - la, pz, pz + lb):
        ax.plot([0.05, 1.5], [z, z], color="0.4", lw=0.5, ls=":")
    ax.add_patch(
        FancyArrowPatch(
            (-0.5, pz - la - 0.18), (0.5, pz - la - 0.18), arrowstyle="<|-|>", mutation_scale=7, color="k", lw=0.7
        )
    )
    ax.text(0.0, pz - la - 0.24, "d_A", ha="center", va="top", fontsize=8)
    ax.add_patch(
        FancyArrowPatch(
            (-0.5, pz + lb + 0.18), (0.5, pz + lb + 0.18), arrowstyle="<|-|>", mutation_scale=7, color="k", lw=0.7
        )
    )
    ax.text(0.0, pz + lb + 0.24, "d_B", ha="center", va="bottom", fontsize=8)
    # thrust bearing C under the pin
    for x in (-0.3, -0.1, 0.1, 0.3):
        ax.add_patch(plt.Circle((x, -1.5), 0.045, fc=BEARING, ec="k", lw=0.5, zorder=4))
    ax.text(-1.35, -1.5, "thrust bearing C\n(Ø d_C, carries f_z)", ha="right", va="center")
    # s along the axis from O to P
    ax.plot([0.05, 2.3], [oz, oz], color="0.4", lw=0.5, ls=":")
    dim(ax, 2.25, pz, oz, "−s  (s < 0 here)", side=1)
    # the reaction at P
    arrow(ax, (0, pz), (0.75, pz + 0.45), color="tab:red", lw=1.6)
    ax.text(0.78, pz + 0.5, "f", color="tab:red", ha="left", va="bottom", fontweight="bold")
    ax.add_patch(
        FancyArrowPatch(
            (-0.12, -0.3),
            (-0.12, 0.3),
            connectionstyle="arc3,rad=-0.9",
            arrowstyle="-|>",
            mutation_scale=9,
            color="tab:purple",
            lw=1.3,
        )
    )
    ax.text(-0.3, 0.42, "n", color="tab:purple", ha="right", va="bottom", fontweight="bold")
    ax.text(
        -2.75,
        -2.75,
        "O: joint origin = URDF child link frame at q = 0 (its y axis points into the page)\n"
        "P: reaction_point = s·a, on the axis (else refused); the reaction (f, n) of link i−1 on\n"
        "   link i acts at P and is reported in the child link frame; A at P − l_a·a, B at P + l_b·a",
        ha="left",
        va="top",
        fontsize=8,
    )
    ax.set_xlim(-2.8, 3.6)
    ax.set_ylim(-3.55, 3.3)


def slider(ax):
    ax.set_title("(b) prismatic joint: slider of link i in a slideway of link i−1", loc="left", fontsize=10)
    # side view: axis to the right
    ax.add_patch(Rectangle((-2.6, -0.95), 5.2, 0.3, fc=PARENT, ec="k", hatch="//", lw=0.8))
    ax.add_patch(Rectangle((-2.6, 0.65), 5.2, 0.3, fc=PARENT, ec="k", hatch="//", lw=0.8))
    ax.text(-2.6, 1.05, "link i−1 (parent): slideway", ha="left", va="bottom")
    ax.add_patch(Rectangle((-1.0, -0.65), 2.0, 1.3, fc=CHILD, ec="k", lw=0.8))
    ax.add_patch(Rectangle((1.0, -0.2), 1.9, 0.4, fc=CHILD, ec="k", lw=0.8))
    ax.text(1.15, -0.3, "link i (child)", ha="left", va="top")
    ax.plot([-2.9, 3.0], [0, 0], color=AXIS, lw=1.0, ls=(0, (6, 3)))
    arrow(ax, (2.9, 0), (3.35, 0), color=AXIS, lw=1.6)
    ax.text(3.05, 0.12, "a (engine z)", color=AXIS, ha="left", va="bottom")
    ax.plot(0, 0, "o", color="tab:red", ms=5, zorder=5)
    ax.text(0.08, 0.08, "centre", color="tab:red", ha="left", va="bottom", fontweight="bold")
    for x in (-1.0, 1.0):
        for y in (-0.65, 0.65):
            ax.plot(x, y, "s", color=BEARING, ms=4)
    ax.add_patch(FancyArrowPatch((-1.0, -1.2), (1.0, -1.2), arrowstyle="<|-|>", mutation_scale=8, color="k", lw=0.8))
    ax.text(0, -1.27, "a (slider length, along the axis)", ha="center", va="top")
    ax.text(
        -2.9,
        -1.75,
        "centre: a point of link i, given in the URDF child link frame;\n"
        "the reaction (f, n) acts there, reported in the child link frame;\n"
        "contact at the 8 corner points (squares: 4 of them)",
        ha="left",
        va="top",
        fontsize=8,
    )
    # cross-section, looking along the axis
    cx, cy = 0.0, -4.15
    ax.add_patch(Rectangle((cx - 1.6, cy - 1.15), 3.2, 2.3, fc=PARENT, ec="k", hatch="//", lw=0.8))
    ax.add_patch(Rectangle((cx - 1.0, cy - 0.6), 2.0, 1.2, fc=CHILD, ec="k", lw=0.8))
    ax.add_patch(plt.Circle((cx, cy), 0.09, fc="white", ec=AXIS, lw=1.2, zorder=5))
    ax.plot(cx, cy, ".", color=AXIS, ms=3, zorder=6)
    arrow(ax, (cx, cy), (cx + 0.8, cy), lw=1.3)
    arrow(ax, (cx, cy), (cx, cy + 0.5), lw=1.3)
    ax.text(cx + 0.82, cy - 0.05, "x_e", ha="left", va="top")
    ax.text(cx + 0.05, cy + 0.5, "y_e", ha="left", va="bottom")
    ax.add_patch(
        FancyArrowPatch(
            (cx - 1.0, cy - 0.8), (cx + 1.0, cy - 0.8), arrowstyle="<|-|>", mutation_scale=8, color="k", lw=0.8
        )
    )
    ax.text(cx - 1.7, cy - 0.8, "b (along x_e)", ha="right", va="center")
    ax.add_patch(
        FancyArrowPatch(
            (cx + 1.25, cy - 0.6), (cx + 1.25, cy + 0.6), arrowstyle="<|-|>", mutation_scale=8, color="k", lw=0.8
        )
    )
    ax.text(cx + 1.7, cy, "c (along y_e)", ha="left", va="center")
    ax.text(-2.9, cy + 1.35, "cross-section, a out of the page:", ha="left", va="bottom", fontsize=8)
    ax.text(
        -2.9,
        cy - 1.35,
        "x_e, y_e: the engine frame's axes, R_a·x and R_a·y in the child link\n"
        "frame (= its x and y when the URDF axis is +z; table in docs/urdf.md)",
        ha="left",
        va="top",
        fontsize=8,
    )
    ax.set_xlim(-3.0, 4.4)
    ax.set_ylim(-6.2, 1.6)


def main():
    fig, (a, b) = plt.subplots(
        1, 2, figsize=(12.5, 6.6), layout="constrained", gridspec_kw={"width_ratios": [1.0, 1.05]}
    )
    for ax in (a, b):
        ax.set_aspect("equal")
        ax.axis("off")
    revolute(a)
    slider(b)
    fig.savefig(
        OUT, bbox_inches="tight", pad_inches=0.2, **({"metadata": {"Date": None}} if OUT.suffix == ".svg" else {})
    )
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
