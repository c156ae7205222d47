"""Population tables and the landmark dimensions a manikin is built from.

The tables are copies of ``shared/data/anthropometry`` kept in ``mtlc/body/data`` with their
citation header lines, so an installed package needs nothing outside itself:

* GB 10000-88 *Human dimensions of Chinese adults* (men 18-60, women 18-55), percentiles
  1, 5, 10, 50, 90, 95, 99 (``gb10000_1988.csv``);
* ANSUR II (Gordon et al. 2014, NATICK/TR-15/007), percentiles computed from the public working
  data sets (``ansur2_summary.csv``);
* Drillis & Contini (1966) stature fractions as tabulated by Winter (``drillis_contini.csv``),
  used only where a table has no landmark for a joint centre.

GB lengths are between surface landmarks, not joint centres, so the skeleton is built from
landmark *heights* (stature, eye, acromion, elbow, crotch, tibiale) and breadths; the derivation
of every joint-centre height is in :func:`dimensions` and in ``docs/body.md``.
"""

from __future__ import annotations

import csv
import functools
from dataclasses import dataclass, field
from importlib.resources import files
from typing import Literal

Sex = Literal["male", "female"]
Population = Literal["gb10000_1988", "ansur2"]

POPULATIONS: tuple[str, ...] = ("gb10000_1988", "ansur2")
SEXES: tuple[str, ...] = ("male", "female")
PERCENTILES: tuple[int, ...] = (1, 5, 10, 50, 90, 95, 99)

_FILES = {
    "gb10000_1988": "gb10000_1988.csv",
    "ansur2": "ansur2_summary.csv",
    "drillis_contini": "drillis_contini.csv",
    "joint_limits": "joint_limits.csv",
    "segment_mass": "segment_mass.csv",
}


def _read(name: str) -> tuple[str, list[dict[str, str]]]:
    """Return (citation header text, rows) of a packaged CSV; '#' lines are the citation."""
    text = (files("mtlc.body") / "data" / _FILES[name]).read_text(encoding="utf-8")
    head = [ln[1:].strip() for ln in text.splitlines() if ln.startswith("#")]
    body = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    return " ".join(head), list(csv.DictReader(body))


@functools.cache
def table_rows(name: str) -> tuple[dict[str, str], ...]:
    """Rows of a packaged table (cached, read-only use)."""
    return tuple(_read(name)[1])


@functools.cache
def citation(name: str) -> str:
    """The citation header carried by a packaged table, e.g. ``citation("gb10000_1988")``."""
    return _read(name)[0]


@functools.cache
def _gb() -> dict[tuple[str, int, str], float]:
    out: dict[tuple[str, int, str], float] = {}
    for r in table_rows("gb10000_1988"):
        out[(r["sex"], int(r["percentile"]), r["measure"])] = float(r["value"])
    return out


@functools.cache
def _ansur() -> dict[tuple[str, int, str], float]:
    out: dict[tuple[str, int, str], float] = {}
    for r in table_rows("ansur2"):
        for p in PERCENTILES:
            out[(r["sex"], p, r["measure"])] = float(r[f"p{p}"])
    return out


@functools.cache
def _dc() -> dict[str, float]:
    return {r["measure"]: float(r["fraction_of_H"]) for r in table_rows("drillis_contini")}


def measure(population: str, sex: str, percentile: int, name: str) -> float:
    """One table value in the table's own unit (mm, or kg for weight)."""
    _check(population, sex, percentile)
    table = _gb() if population == "gb10000_1988" else _ansur()
    try:
        return table[(sex, percentile, name)]
    except KeyError:
        raise KeyError(f"{population} has no measure {name!r} for {sex} P{percentile}") from None


def measures(population: str) -> tuple[str, ...]:
    """Names of the measures a population table holds."""
    table = _gb() if population == "gb10000_1988" else _ansur()
    return tuple(sorted({k[2] for k in table}))


def _check(population: str, sex: str, percentile: int) -> None:
    if population not in POPULATIONS:
        raise ValueError(f"unknown population {population!r}; choose one of {POPULATIONS}")
    if sex not in SEXES:
        raise ValueError(f"unknown sex {sex!r}; choose 'male' or 'female'")
    if percentile not in PERCENTILES:
        raise ValueError(f"percentile must be one of {PERCENTILES}, not {percentile!r}")


# Hip joint centre above crotch height, as a fraction of stature.  GB 10000-88 has no
# trochanter height; ANSUR II gives trochanterion - crotch height = 0.031 H (men) and
# 0.039 H (women) from the means in ansur2_summary.csv, and the hip joint centre lies close
# to the level of the greater trochanter's tip.
HIP_ABOVE_CROTCH = {"male": (900.9 - 845.9) / 1756.2, "female": (845.4 - 782.3) / 1628.5}
# Glenohumeral joint centre below the acromion, as a fraction of the acromion-elbow height
# difference (a common gait-lab rule of thumb; an assumption documented in docs/body.md).
SHOULDER_BELOW_ACROMION = 0.17
# Atlanto-occipital (head) joint below eye height, fraction of stature (assumption).
HEAD_JOINT_BELOW_EYE = 0.04
# C7/T1 (neck joint) above acromion height, fraction of stature (assumption, cervicale is
# about 0.04 H above acromion in ANSUR-type data; the joint centre lies in front and below).
NECK_ABOVE_ACROMION = 0.03
# Sternoclavicular joint below acromion, fraction of stature (suprasternale ~0.01 H below
# acromion, the joint centre a little lower).
STERNOCLAVICULAR_BELOW_ACROMION = 0.02


@dataclass(frozen=True)
class Dimensions:
    """Landmark and joint-centre dimensions of one manikin, in metres and kilograms.

    Heights are from the floor at the neutral standing posture. ``notes`` says where each
    value came from, so a report can show the derivation next to the number.
    """

    population: str
    sex: str
    percentile: int
    stature: float
    mass: float
    eye_height: float
    acromion_height: float
    elbow_height: float
    wrist_height: float
    hip_height: float
    knee_height: float
    ankle_height: float
    biacromial_breadth: float
    hip_breadth: float
    hand_length: float
    foot_length: float
    foot_breadth: float
    notes: dict[str, str] = field(default_factory=dict, compare=False)

    @property
    def shoulder_height(self) -> float:
        """Glenohumeral joint-centre height (below the acromion landmark)."""
        return self.acromion_height - SHOULDER_BELOW_ACROMION * (
            self.acromion_height - self.elbow_height
        )


def dimensions(
    population: str = "gb10000_1988", sex: str = "male", percentile: int = 50
) -> Dimensions:
    """Derive the dimensions a skeleton needs from one table row set.

    Every sex/percentile takes all its measures at the same percentile, the usual (and
    knowingly approximate) way of building percentile manikins (seed 000, Jack).
    """
    _check(population, sex, percentile)

    def m(name: str) -> float:
        return measure(population, sex, percentile, name) / 1000.0

    dc = _dc()
    notes: dict[str, str] = {}
    if population == "gb10000_1988":
        h = m("stature")
        forearm = m("forearm_length")
        dims = Dimensions(
            population=population,
            sex=sex,
            percentile=percentile,
            stature=h,
            mass=measure(population, sex, percentile, "weight_kg"),
            eye_height=m("eye_height"),
            acromion_height=m("shoulder_height"),
            elbow_height=m("elbow_height"),
            # radiale-stylion length ~ elbow-wrist joint-centre distance (de Leva 1996:
            # EJC-STYL 0.2669 m vs EJC-WJC 0.2689 m for the male reference subject).
            wrist_height=m("elbow_height") - forearm,
            hip_height=m("crotch_height") + HIP_ABOVE_CROTCH[sex] * h,
            knee_height=m("tibiale_height"),
            ankle_height=dc["ankle_height"] * h,
            biacromial_breadth=m("shoulder_breadth(biacromial)"),
            hip_breadth=m("hip_breadth"),
            hand_length=m("hand_length"),
            foot_length=m("foot_length"),
            foot_breadth=m("foot_breadth"),
            notes=notes,
        )
        notes.update(
            stature="GB 10000-88 stature",
            eye_height="GB 10000-88 eye height",
            acromion_height="GB 10000-88 shoulder height (acromion)",
            elbow_height="GB 10000-88 elbow height (radiale) = elbow joint centre",
            wrist_height="elbow height - GB forearm length (radiale-stylion)",
            hip_height="GB crotch height + (trochanterion - crotch) ratio from ANSUR II",
            knee_height="GB tibiale height = knee joint line",
            ankle_height="Drillis-Contini 0.039 H (GB has no malleolus height)",
        )
        return dims
    h = m("stature")
    # ANSUR II summary has no standing eye or elbow height: eye height = stature - (sitting
    # height - sitting eye height); elbow joint = wrist height + radiale-stylion length.
    dims = Dimensions(
        population=population,
        sex=sex,
        percentile=percentile,
        stature=h,
        mass=measure(population, sex, percentile, "weight_kg"),
        eye_height=h - (m("sitting_height") - m("eye_height_sitting")),
        acromion_height=m("acromial_height(shoulder)"),
        elbow_height=m("wrist_height") + m("radiale_stylion_length(forearm)"),
        wrist_height=m("wrist_height"),
        hip_height=m("trochanterion_height"),
        knee_height=m("tibial_height"),
        ankle_height=m("lateral_malleolus_height"),
        biacromial_breadth=m("biacromial_breadth"),
        hip_breadth=m("hip_breadth"),
        hand_length=m("hand_length"),
        foot_length=m("foot_length"),
        foot_breadth=dc["foot_width"] * h,
        notes=notes,
    )
    notes.update(
        stature="ANSUR II stature",
        eye_height="stature - (sitting height - sitting eye height)",
        acromion_height="ANSUR II acromial height",
        elbow_height="wrist height + radiale-stylion length",
        wrist_height="ANSUR II wrist height",
        hip_height="ANSUR II trochanterion height",
        knee_height="ANSUR II tibial height",
        ankle_height="ANSUR II lateral malleolus height",
        foot_breadth="Drillis-Contini 0.055 H",
    )
    return dims


def drillis_contini() -> dict[str, float]:
    """Drillis-Contini stature fractions (Winter Fig. 4.1), for checks and fallbacks."""
    return dict(_dc())
