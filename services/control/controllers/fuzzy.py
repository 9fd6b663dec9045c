"""Mamdani fuzzy inference for gain scheduling: 7 terms, 49 rules, centroid (vectorised).

Inputs e and de are normalised to the universe [-3, 3] and described by seven triangular
terms NB, NM, NS, ZO, PS, PM, PB centred at -3 .. 3 (unit half-width; values beyond the
universe are clipped, which makes NB and PB shoulders). Each rule "if e is A_i and de is B_j
then dK is C_ij" fires with min(mu_Ai(e), mu_Bj(de)); the clipped consequents are aggregated
by max and defuzzified by their centroid on a 121-point grid of the output universe. Only
the (at most four) rules that fire are visited, and the aggregation reduces over the terms
first: the same floats as over all 49 rules, at a third of the cost
(docs/notes/planner-fuzzy-inference-firing-rules.md).

The three tables are the fuzzy self-tuning PID tables widely reproduced in the fuzzy-PID
literature (rows: e = NB .. PB, columns: de = NB .. PB):

    dKp                          dKi                          dKd
NB  PB PB PM PM PS ZO ZO        NB NB NM NM NS ZO ZO         PS NS NB NB NB NM PS
NM  PB PB PM PS PS ZO NS        NB NB NM NS NS ZO ZO         PS NS NB NM NM NS ZO
NS  PM PM PM PS ZO NS NS        NB NM NS NS ZO PS PS         ZO NS NM NM NS NS ZO
ZO  PM PM PS ZO NS NM NM        NM NM NS ZO PS PM PM         ZO NS NS NS NS NS ZO
PS  PS PS ZO NS NS NM NM        NM NS ZO PS PS PM PB         ZO ZO ZO ZO ZO ZO ZO
PM  PS ZO NS NM NM NM NB        ZO ZO PS PS PM PB PB         PB NS PS PS PS PS PB
PB  ZO ZO NM NM NM NB NB        ZO ZO PS PM PM PB PB         PB PM PM PM PS PS PB

Their reasoning: a large error wants a large Kp, a small Ki (no wind-up) and a small Kd; a
medium error a smaller Kp and a moderate Kd; near the set point a larger Ki for zero
steady-state error and a Kd that depends on how fast the error moves.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

TERMS = ("NB", "NM", "NS", "ZO", "PS", "PM", "PB")
_INDEX = {name: i - 3 for i, name in enumerate(TERMS)}  # term -> centre in [-3, 3]

DKP_TABLE = """
PB PB PM PM PS ZO ZO
PB PB PM PS PS ZO NS
PM PM PM PS ZO NS NS
PM PM PS ZO NS NM NM
PS PS ZO NS NS NM NM
PS ZO NS NM NM NM NB
ZO ZO NM NM NM NB NB
"""
DKI_TABLE = """
NB NB NM NM NS ZO ZO
NB NB NM NS NS ZO ZO
NB NM NS NS ZO PS PS
NM NM NS ZO PS PM PM
NM NS ZO PS PS PM PB
ZO ZO PS PS PM PB PB
ZO ZO PS PM PM PB PB
"""
DKD_TABLE = """
PS NS NB NB NB NM PS
PS NS NB NM NM NS ZO
ZO NS NM NM NS NS ZO
ZO NS NS NS NS NS ZO
ZO ZO ZO ZO ZO ZO ZO
PB NS PS PS PS PS PB
PB PM PM PM PS PS PB
"""


def parse_table(text: str) -> npt.NDArray[np.int64]:
    """A 7x7 table of term names -> consequent centres in [-3, 3]."""
    rows = [line.split() for line in text.strip().splitlines()]
    if len(rows) != 7 or any(len(r) != 7 for r in rows):
        raise ValueError("rule table: expected 7 rows of 7 terms")
    return np.array([[_INDEX[name] for name in row] for row in rows], dtype=np.int64)


_CENTRES = np.arange(-3.0, 4.0)  # (7,)
_GRID = np.linspace(-3.0, 3.0, 121)  # output universe samples


def memberships(x: float | FloatArray) -> FloatArray:
    """Triangular memberships of the 7 terms at x (clipped to [-3, 3]); last axis = term."""
    xc = np.clip(np.asarray(x, dtype=np.float64), -3.0, 3.0)
    return np.maximum(0.0, 1.0 - np.abs(xc[..., None] - _CENTRES))


_GRID_MU = memberships(_GRID).T  # (7 terms, 121 grid points)
_GRID_MU3 = np.ascontiguousarray(_GRID_MU[:, None, :])  # (7, 1, 121): the terms first


def _active(x: float) -> list[tuple[int, float]]:
    """The terms (index 0..6, membership > 0) at x: memberships() without the zeros."""
    xc = min(max(float(x), -3.0), 3.0)
    out: list[tuple[int, float]] = []
    if xc != xc:  # NaN: no term holds
        return out
    # a term is non-zero within 1 of its centre: only the centres either side of xc can be
    # (each |xc - c| >= 1 of the others rounds to >= 1 as well), tried in the same order
    below = math.floor(xc)
    for c in (below, below + 1):
        if c <= 3:
            mu = 1.0 - abs(xc - float(c))
            if mu > 0.0:
                out.append((c + 3, mu))
    return out


class MamdaniTables:
    """Several 49-rule tables sharing the inputs, evaluated together."""

    def __init__(self, *tables: str) -> None:
        rules = np.stack([parse_table(t) for t in tables])  # (n, 7, 7)
        # consequent term index (0..6) of rule (i, j) of each table, as nested tuples
        self._rules = tuple(tuple(tuple(int(k) + 3 for k in row) for row in r) for r in rules)

    def infer(self, e_n: float, de_n: float) -> FloatArray:
        """Centroid outputs (one per table) in [-3, 3] for normalised inputs."""
        # strength of each output term: max over the rules concluding it of their firing
        # strength min(mu_e, mu_de). A triangular term of unit half-width is non-zero for at
        # most two terms of each input, so at most four rules fire: only those are visited
        # (the others fire with 0, which the max over non-negative strengths ignores)
        strength = np.zeros((len(self._rules), 7))
        terms_de = _active(de_n)
        fired = False
        for i, a in _active(e_n):
            for j, b in terms_de:
                w = min(a, b)
                fired = True
                for n, table in enumerate(self._rules):
                    k = table[i][j]
                    if w > strength[n, k]:
                        strength[n, k] = w
        # clipped consequents, aggregated by max: (7 terms, n, 121) reduced over the terms
        agg = np.maximum.reduce(np.minimum(strength.T[:, :, None], _GRID_MU3), axis=0)
        den = agg.sum(axis=1)
        # a rule that fires (w > 0) leaves min(w, 1) at its consequent's centre, a grid point,
        # in every table: each den > 0, and the guard against 0 / 0 (no rule fires: a NaN
        # input) is needed only then
        out: FloatArray = (agg @ _GRID) / (den if fired else np.where(den > 0.0, den, 1.0))
        return out
