"""Base parameters: the combinations of the standard parameters that joint torques identify.

The joint torques are linear in the parameters, τ = W(q, q̇, q̈) π, but not every column of W
is independent of the others for every motion the chain can make: link 1 turns about a fixed
axis, so only its inertia about that axis acts; a joint's mass and first moment about its own
axis act only through the next joint's; and so on (the grouping rules of Gautier and Khalil).
The data then fix the *base parameters* β = π_b + K π_d: each independent column's parameter
plus the combination of the dependent ones that acts through the same torque.

They are found numerically, as robotics identification does it (Gautier, 1990): W is stacked
at many random states (positions, velocities and accelerations drawn over the joints' ranges),
each column scaled to unit norm, and taken column by column in a fixed order, link 1 to link n
and within a link I_xx, I_xy, I_xz, I_yz, I_zz, m·c_x, m·c_y, I_yy, m·c_z, m (the order of the
grouping rules, which keep the first ones and fold the last three into the link before). A
column is independent where what is left of it after projecting out the independent ones before
it exceeds ``RANK_TOLERANCE`` of its norm (Gram-Schmidt, twice for accuracy), else it is their
combination, W_d = W_b K (K by least squares). Then W π = W_b (π_b + K π_d) = W_b β, and each
base parameter reads as its own standard parameter plus the dependent ones folded into it.
A column of W that is zero at every state (a parameter that
acts on no joint torque, such as link 1's inertia about axes other than its joint's, which only
loads the bearings) is dependent with a zero column of K: no base parameter holds it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# A column whose part independent of the columns before it is below this fraction of its norm
# is their combination: far above the rounding of a few thousand rows (1e-16 × rows), far
# below a column that carries a parameter of its own.
RANK_TOLERANCE = 1e-8
# A column below this fraction of the largest is rounding (a parameter that moves no torque,
# whose column the regressor's sums leave at 1e-17 of the others instead of 0: m·c_z of a link
# whose joint axis passes through it, measured 2e-17 for the iiwa's link 2), not a parameter.
ZERO_COLUMN = 1e-12
# Coefficients of K below this are rounding, not a combination.
COEFFICIENT_TOLERANCE = 1e-9


@dataclass(frozen=True)
class BaseParameters:
    """The base parameters of a chain: ``independent`` and ``dependent`` index the standard
    parameters (``names``); β = π[independent] + K @ π[dependent]."""

    names: tuple  # the standard parameters' names, as the regressor orders its columns
    independent: np.ndarray  # r indices
    dependent: np.ndarray  # p - r indices
    K: np.ndarray  # r × (p - r)

    @property
    def count(self) -> int:
        return len(self.independent)

    def matrix(self) -> np.ndarray:
        """The r × p matrix B with β = B π."""
        B = np.zeros((self.count, len(self.names)))
        B[np.arange(self.count), self.independent] = 1.0
        B[:, self.dependent] = self.K
        return B

    def of(self, pi) -> np.ndarray:
        """β of the standard parameters ``pi``."""
        return self.matrix() @ np.asarray(pi, dtype=np.float64)

    def columns(self, W) -> np.ndarray:
        """The base regressor W_b (the independent columns of W, whose last axis is p)."""
        return np.asarray(W)[..., self.independent]

    def unidentifiable(self) -> list:
        """The standard parameters that act on no torque (zero in every combination)."""
        B = self.matrix()
        return [self.names[j] for j in range(len(self.names)) if not np.any(B[:, j])]

    def describe(self) -> list:
        """Each base parameter as a user reads it: "I_zz[1] + 0.0625·m[2] + I_yy[2]"."""
        out = []
        for a, j in enumerate(self.independent):
            terms = [self.names[j]]
            for b, d in enumerate(self.dependent):
                c = self.K[a, b]
                if c == 0.0:
                    continue
                sign = "−" if c < 0 else "+"
                one = abs(abs(c) - 1.0) < 1e-9
                terms.append(f"{sign} {self.names[d]}" if one else f"{sign} {abs(c):.6g}·{self.names[d]}")
            out.append(" ".join(terms))
        return out


# The order in which columns are taken (within a link): the grouping rules' kept parameters
# first, those they fold into the link before last.
PREFERRED = ("I_xx", "I_xy", "I_xz", "I_yz", "I_zz", "mc_x", "mc_y", "I_yy", "mc_z", "m")


def _order(names) -> list:
    def key(j):
        kind, _, link = names[j].partition("[")
        return (
            int(link.rstrip("]")) if link.rstrip("]").isdigit() else 0,
            PREFERRED.index(kind) if kind in PREFERRED else len(PREFERRED),
            j,
        )

    return sorted(range(len(names)), key=key)


def base_parameters(W, names) -> BaseParameters:
    """The base parameters of the stacked regressor ``W`` (rows × p, from states rich enough to
    show every combination the chain can make: :func:`random_states`), its columns named by
    ``names`` ("I_zz[2]", ...; other names are taken last, in their order)."""
    W = np.asarray(W, dtype=np.float64)
    if W.ndim != 2 or W.shape[1] != len(names):
        raise ValueError(f"the regressor is {W.shape}, its {len(names)} parameters need rows × {len(names)}")
    if not np.all(np.isfinite(W)):
        raise ValueError("the regressor has values that are not finite")
    basis = np.zeros((W.shape[0], 0))
    independent, dependent = [], []
    largest = float(np.linalg.norm(W, axis=0).max(initial=0.0))
    for j in _order(list(names)):
        column = W[:, j]
        norm = np.linalg.norm(column)
        if norm <= ZERO_COLUMN * largest:  # rounding of a parameter that moves no torque
            dependent.append(j)
            continue
        u = column / norm
        for _ in range(2):  # classical Gram-Schmidt, repeated: orthogonal to rounding
            u = u - basis @ (basis.T @ u)
        if np.linalg.norm(u) > RANK_TOLERANCE:
            basis = np.column_stack([basis, u / np.linalg.norm(u)])
            independent.append(j)
        else:
            dependent.append(j)
    independent, dependent = np.array(independent, dtype=int), np.array(dependent, dtype=int)
    if len(independent) and len(dependent):
        K = np.linalg.lstsq(W[:, independent], W[:, dependent], rcond=None)[0]
    else:
        K = np.zeros((len(independent), len(dependent)))
    K[np.abs(K) < COEFFICIENT_TOLERANCE * np.abs(K).max(initial=1.0)] = 0.0
    order = np.argsort(independent)
    return BaseParameters(tuple(names), independent[order], dependent, K[order])


def random_states(n: int, count: int, seed: int, limits=None) -> np.ndarray:
    """``count`` rows of [q(n), q̇(n), q̈(n)]: q uniform within ``limits`` (n pairs, default ±π),
    q̇ and q̈ standard normal (rad/s, rad/s²; m/s and m/s² for a prismatic joint whose limits
    say so); seeded, for :func:`base_parameters`."""
    rng = np.random.default_rng(seed)
    low, high = (-np.pi, np.pi) if limits is None else np.array(limits, dtype=np.float64).reshape(n, 2).T
    q = low + (high - low) * rng.random((count, n))
    return np.hstack([q, rng.standard_normal((count, n)), rng.standard_normal((count, n))])
