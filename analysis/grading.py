"""Clump breakage: grading curves and breakage indices of fragment records (SPEC 1.2 and 4,
thesis 4.5 and figure 4.25).

This module owns the grading analysis of the ``/fragments`` records (layout in
`pdem.format.schema`): grading curves, the thesis's figures (mass in fragments of at least 135
spheres, mass in single spheres), the breakage indices between a reference record and each later
one, and their table, JSON and PNGs (``grading.txt``, ``grading.json``, ``grading.png``,
``breakage.png``: the indices per record, e.g. per passage of a track, with the bonds broken
where the records hold the intact bonds). The
indices are defined in ``docs/breakage_indices.md``; in short, with f_i the mass fraction of
fragment i, d its size and P(x) the mass fraction passing x:

- by number: the thesis's text (4.5) counts fragments ("90 % of all clumps consist of 135 and
  more spheres", "the number of clumps of 135 and more spheres fell to ca. 15 %", "about 30 %
  single spheres") while its figure 4.25 is labelled by mass; both are reported:
  ``count_single`` and ``count_large`` are fractions of the number of fragments.
- size: number of member spheres n [-], or the equivalent sieve diameter
  d = (6 m / (pi rho))^(1/3) [m] (the sphere of the fragment's mass). The smallest possible
  fragment is one sphere of the smallest member radius: d_min = 2 r_min.
- passing: P(x) = sum of f_i over fragments with size <= x (cumulative, "% finer").
- Marsal (1967): B_g = sum over size fractions k of max(W_k,0 - W_k,1, 0), W_k the percentage
  of mass retained in fraction k before (0) and after (1) [%]. Fractions: every member count n
  (``marsal_members``) and the sieve series (``marsal_sieves``).
- Hardin (1985): breakage potential B_p = sum f_i log10(d_i / d_min) (Hardin's 0.074 mm cut-off
  replaced by d_min, one sphere), total breakage B_t = B_p,0 - B_p,1, relative breakage
  B_r = B_t / B_p,0 [-].
- Indraratna et al. (2005) Ballast Breakage Index: BBI = A / (A + B) on a log10 d axis between
  d_min and d_max (the largest fragment), A = area between the reference and the current
  grading curve, B = area between the current curve and the boundary of maximum breakage,
  here "every fragment a single sphere" (P = 1 for d >= d_min). With that boundary
  A + B = B_p,0 and A = B_t, so BBI equals B_r: both are computed (by different routes) and
  reported.

Units: [kg], [m], [kg/m^3]; tables and plots show [mm] and [%]. Imports numpy, `pdem.format`
and this package; matplotlib only when a plot is drawn.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from pdem.format.groups import FragmentRecord, Fragments, read_fragments
from pdem.format.read import results_file

from .figures import default_out

INTACT_MEMBERS = 135     # spheres of an intact Nottingham grain (Lim 2004; thesis 4.1.1)
SIEVE_RATIO = 2 ** 0.5   # default sieve series: d_min * SIEVE_RATIO**k
TOL = 1e-9               # relative: a size passes an aperture a if size <= a (1 + TOL)
MM, PERCENT = 1e3, 1e2


def sieve_diameter(mass, density) -> np.ndarray:
    """Equivalent sieve diameter d = (6 m / (pi rho))^(1/3) [m] of fragments of mass m [kg]."""
    return np.cbrt(6.0 * np.asarray(mass, dtype=np.float64) / (np.pi * float(density)))


def grading_curve(sizes, mass):
    """Cumulative mass fraction passing at each distinct size.

    Parameters
    ----------
    sizes : array
        Size of each fragment (member count [-] or sieve diameter [m]).
    mass : array [kg]

    Returns
    -------
    x : ndarray
        Distinct sizes, ascending.
    passing : ndarray [-]
        Mass fraction of the fragments of size <= x (the last entry is 1).
    """
    sizes, mass = np.asarray(sizes, dtype=np.float64), np.asarray(mass, dtype=np.float64)
    x, inverse = np.unique(sizes, return_inverse=True)
    per_size = np.bincount(inverse.ravel(), weights=mass, minlength=len(x))
    cumulative = np.cumsum(per_size)
    return x, cumulative / cumulative[-1]


def passing(sizes, mass, apertures) -> np.ndarray:
    """Mass fraction [-] of fragments of size <= each aperture (within the relative `TOL`)."""
    sizes = np.asarray(sizes, dtype=np.float64)
    mass = np.asarray(mass, dtype=np.float64)
    order = np.argsort(sizes)
    cumulative = np.concatenate(([0.0], np.cumsum(mass[order])))
    k = np.searchsorted(sizes[order], np.asarray(apertures, dtype=np.float64) * (1.0 + TOL),
                        side="right")
    return cumulative[k] / cumulative[-1]


def sieve_series(d_min: float, d_max: float, ratio: float = SIEVE_RATIO) -> np.ndarray:
    """Apertures d_min * ratio**k [m], k = 0, 1, ... up to the first >= d_max."""
    k = max(0, math.ceil(math.log(d_max / d_min) / math.log(ratio) - TOL))
    return d_min * ratio ** np.arange(k + 1)


def sieve_class(d, apertures) -> np.ndarray:
    """Size fraction of each fragment: the number of apertures it does not pass (0 = pan)."""
    return np.searchsorted(np.asarray(apertures, dtype=np.float64) * (1.0 + TOL),
                           np.asarray(d, dtype=np.float64), side="left")


def marsal(classes0, mass0, classes1, mass1) -> float:
    """Marsal's breakage factor B_g [%] between two gradings.

    B_g = sum over fractions k of max(W_k,0 - W_k,1, 0), W_k the percentage of the mass in
    fraction k (retained between consecutive sieves) before (0) and after (1).

    Parameters
    ----------
    classes0, classes1 : array
        Size fraction of each fragment (any labels: member counts, `sieve_class`).
    mass0, mass1 : array [kg]
    """
    w0, w1 = _percent_by_class(classes0, mass0), _percent_by_class(classes1, mass1)
    return float(sum(max(w0.get(k, 0.0) - w1.get(k, 0.0), 0.0) for k in w0))


def hardin_potential(d, mass, d_min: float) -> float:
    """Hardin's breakage potential B_p = sum f_i log10(d_i / d_min) [-] (sizes below d_min
    count 0), f_i the mass fractions."""
    d, mass = np.asarray(d, dtype=np.float64), np.asarray(mass, dtype=np.float64)
    b = np.log10(np.maximum(d / d_min, 1.0))
    return float(np.sum(mass * b) / np.sum(mass))


def hardin(d0, mass0, d1, mass1, d_min: float):
    """Hardin's (1985) indices between a reference (0) and a current (1) grading.

    Returns
    -------
    bp0, bp1 : float [-]
        Breakage potentials, `hardin_potential`.
    bt : float [-]
        Total breakage B_t = B_p,0 - B_p,1.
    br : float [-]
        Relative breakage B_r = B_t / B_p,0 (NaN if B_p,0 = 0: nothing left to break).
    """
    bp0, bp1 = hardin_potential(d0, mass0, d_min), hardin_potential(d1, mass1, d_min)
    bt = bp0 - bp1
    return bp0, bp1, bt, bt / bp0 if bp0 > 0 else float("nan")


def ballast_breakage_index(d0, mass0, d1, mass1, d_min: float, d_max: float | None = None):
    """Indraratna et al.'s (2005) Ballast Breakage Index BBI = A / (A + B) [-].

    Areas on the plane (log10 d, passing fraction) between d_min and d_max: A between the
    reference (0) and current (1) grading curves, B between the current curve and the boundary
    of maximum breakage, P = 1 for d >= d_min (every fragment a single sphere).

    Parameters
    ----------
    d0, d1 : array [m]
        Sieve diameters of the fragments.
    mass0, mass1 : array [kg]
    d_min : float [m]
        Size of one sphere, the smallest fragment.
    d_max : float [m], optional
        Upper end of the axis; default the largest fragment of either grading.

    Returns
    -------
    a, b : float [-] (decades of d times fraction)
    bbi : float [-] (NaN if A + B = 0)
    """
    if d_max is None:
        d_max = float(max(np.max(d0), np.max(d1), d_min))
    span = math.log10(d_max / d_min)
    area0 = _passing_area(d0, mass0, d_min, d_max)
    area1 = _passing_area(d1, mass1, d_min, d_max)
    a, b = area1 - area0, span - area1
    return a, b, a / (a + b) if a + b > 0 else float("nan")


@dataclass(frozen=True)
class RecordSummary:
    """The thesis's figures of one record.

    label, step [-], time [s], n_fragments [-], mass [kg] (total), fraction_single [-] (mass in
    single spheres), fraction_large [-] (mass in fragments of >= `intact_members` spheres),
    fraction_intact [-] (mass in clumps still in one piece; NaN without clump ids), d50 [m]
    (sieve diameter passed by half the mass), d_max [m] (largest fragment); count_single and
    count_large [-]: fractions of the number of fragments that are single spheres and that have
    >= `intact_members` spheres (the thesis's text counts fragments).
    """

    label: str
    step: int
    time: float
    n_fragments: int
    mass: float
    fraction_single: float
    fraction_large: float
    fraction_intact: float
    d50: float
    d_max: float
    count_single: float
    count_large: float


@dataclass(frozen=True)
class Breakage:
    """Breakage indices of a record against the reference (see the module docstring).

    marsal_members, marsal_sieves [%]; hardin_bp0, hardin_bp, hardin_bt, hardin_br [-];
    bbi_a, bbi_b, bbi [-]; d_max [m] (upper end of the BBI axis).
    """

    reference: str
    label: str
    marsal_members: float
    marsal_sieves: float
    hardin_bp0: float
    hardin_bp: float
    hardin_bt: float
    hardin_br: float
    bbi_a: float
    bbi_b: float
    bbi: float
    d_max: float


@dataclass(frozen=True)
class GradingAnalysis:
    """Everything derived from the fragment records of one file.

    Attributes
    ----------
    fragments : Fragments
    d_min : float [m]
        Sieve diameter of one sphere of the smallest member radius.
    sieves : ndarray [m]
        Sieve series of the tables and of ``marsal_sieves``.
    intact_members : int
    summaries : tuple of RecordSummary (record order)
    reference : str
    breakage : tuple of Breakage (every record after the reference)
    notes : tuple of str
    """

    fragments: Fragments
    d_min: float
    sieves: np.ndarray
    intact_members: int
    summaries: tuple
    reference: str
    breakage: tuple
    notes: tuple

    def diameter(self, record: FragmentRecord) -> np.ndarray:
        return sieve_diameter(record.mass, self.fragments.density)


def summarise(record: FragmentRecord, density: float,
              intact_members: int = INTACT_MEMBERS) -> RecordSummary:
    """The thesis's figures of one record (`RecordSummary`)."""
    n, m = record.n_members, record.mass
    total = float(m.sum())
    d = sieve_diameter(m, density)
    x, p = grading_curve(d, m)
    intact = float("nan")
    if record.clump is not None:
        ids, counts = np.unique(record.clump, return_counts=True)
        whole = ids[(counts == 1) & (ids >= 0)]
        intact = float(m[np.isin(record.clump, whole)].sum() / total)
    return RecordSummary(
        label=record.label, step=record.step, time=record.time, n_fragments=len(m), mass=total,
        fraction_single=float(m[n == 1].sum() / total),
        fraction_large=float(m[n >= intact_members].sum() / total),
        fraction_intact=intact, d50=float(x[np.searchsorted(p, 0.5 - TOL)]),
        d_max=float(d.max()), count_single=float(np.mean(n == 1)),
        count_large=float(np.mean(n >= intact_members)))


def breakage(reference: FragmentRecord, record: FragmentRecord, density: float, d_min: float,
             sieves) -> Breakage:
    """All breakage indices of `record` against `reference` (`Breakage`)."""
    d0, d1 = sieve_diameter(reference.mass, density), sieve_diameter(record.mass, density)
    bp0, bp1, bt, br = hardin(d0, reference.mass, d1, record.mass, d_min)
    d_max = float(max(d0.max(), d1.max(), d_min))
    a, b, bbi = ballast_breakage_index(d0, reference.mass, d1, record.mass, d_min, d_max)
    return Breakage(
        reference=reference.label, label=record.label,
        marsal_members=marsal(reference.n_members, reference.mass, record.n_members,
                              record.mass),
        marsal_sieves=marsal(sieve_class(d0, sieves), reference.mass,
                             sieve_class(d1, sieves), record.mass),
        hardin_bp0=bp0, hardin_bp=bp1, hardin_bt=bt, hardin_br=br, bbi_a=a, bbi_b=b, bbi=bbi,
        d_max=d_max)


def analyse_grading(fragments: Fragments, reference: str | None = None,
                    intact_members: int = INTACT_MEMBERS, sieves=None) -> GradingAnalysis:
    """Summaries of every record and the indices of every later record against the reference.

    Parameters
    ----------
    fragments : Fragments
        From `pdem.format.groups.read_fragments`.
    reference : str, optional
        Label of the reference record; default the first.
    intact_members : int
        Threshold of `RecordSummary.fraction_large` (135: the Nottingham grain).
    sieves : array [m], optional
        Sieve apertures; default d_min * sqrt(2)**k up to the largest fragment.

    Raises
    ------
    ValueError
        Unknown reference label, bad threshold or sieves.
    """
    records = fragments.records
    if reference is None:
        ref_index = 0
    else:
        labels = [r.label for r in records]
        if reference not in labels:
            raise ValueError(f"no fragment record {reference!r} (records: {', '.join(labels)})")
        ref_index = labels.index(reference)
    if int(intact_members) < 1:
        raise ValueError(f"intact_members = {intact_members}: must be >= 1")
    rho = fragments.density
    d_min = 2.0 * fragments.member_radius_min
    d_all = np.concatenate([sieve_diameter(r.mass, rho) for r in records])
    notes = []
    if d_all.min() < d_min * (1.0 - 1e-6):
        notes.append(f"a fragment of sieve diameter {d_all.min() * MM:.4g} mm is smaller than "
                     f"one sphere (d_min = {d_min * MM:.4g} mm): density or member_radius_min "
                     f"do not fit the masses; Hardin and BBI count it as d_min")
    if sieves is None:
        sieves = sieve_series(d_min, max(float(d_all.max()), d_min))
    sieves = np.asarray(sieves, dtype=np.float64)
    if sieves.ndim != 1 or len(sieves) < 1 or np.any(np.diff(sieves) <= 0) or sieves[0] <= 0:
        raise ValueError("sieves must be positive apertures in increasing order")
    ref = records[ref_index]
    return GradingAnalysis(
        fragments=fragments, d_min=d_min, sieves=sieves, intact_members=int(intact_members),
        summaries=tuple(summarise(r, rho, int(intact_members)) for r in records),
        reference=ref.label,
        breakage=tuple(breakage(ref, r, rho, d_min, sieves) for r in records[ref_index + 1:]),
        notes=tuple(notes))


# --- output: table, JSON, PNG, command line ---

def grading_lines(result: GradingAnalysis) -> list[str]:
    """The text report: per-record figures, indices, % passing by member count and by sieve."""
    fr = result.fragments
    records = fr.records
    lines = [
        f"pdem fragment grading: {fr.results.path}",
        f"kind {fr.results.kind}, density {fr.density:g} kg/m^3, smallest member sphere "
        f"r = {fr.member_radius_min * MM:.4g} mm (one sphere: d_min = {result.d_min * MM:.4g} mm)",
        f"records: {len(records)}; reference of the indices: {result.reference!r}",
        "sizes: n = member spheres; d = (6 m / (pi rho))^(1/3), the sieve diameter of the "
        "fragment's mass",
        "",
        f"{'record':>16} {'step':>12} {'time':>10} {'fragments':>10} {'mass':>10} "
        f"{'single':>8} {f'n>={result.intact_members}':>8} {'intact':>8} {'d50':>8} "
        f"{'d_max':>8} {'single':>8} {f'n>={result.intact_members}':>8}",
        f"{'':>16} {'[-]':>12} {'[s]':>10} {'[-]':>10} {'[kg]':>10} {'[%]':>8} {'[%]':>8} "
        f"{'[%]':>8} {'[mm]':>8} {'[mm]':>8} {'[%#]':>8} {'[%#]':>8}",
    ]
    for s in result.summaries:
        lines.append(f"{s.label:>16} {s.step:>12d} {s.time:>10.4g} {s.n_fragments:>10d} "
                     f"{s.mass:>10.4g} {s.fraction_single * PERCENT:>8.2f} "
                     f"{s.fraction_large * PERCENT:>8.2f} {_pct(s.fraction_intact):>8} "
                     f"{s.d50 * MM:>8.3f} {s.d_max * MM:>8.3f} {s.count_single * PERCENT:>8.2f} "
                     f"{s.count_large * PERCENT:>8.2f}")
    lines.append("  [%] of the mass; [%#] of the number of fragments (the thesis's text counts fragments)")
    lines += ["", f"breakage indices against {result.reference!r} (docs/breakage_indices.md): "
                  "Marsal B_g by member count and by sieve; Hardin B_p (current), B_t, B_r "
                  "(cut-off d_min); Indraratna BBI = A/(A+B) (boundary: all single spheres)"]
    if result.breakage:
        lines.append(f"{'record':>16} {'B_g(n)':>8} {'B_g(sv)':>8} {'B_p':>8} {'B_t':>8} "
                     f"{'B_r':>8} {'A':>8} {'B':>8} {'BBI':>8}")
        lines.append(f"{'':>16} {'[%]':>8} {'[%]':>8} {'[-]':>8} {'[-]':>8} {'[-]':>8} "
                     f"{'[-]':>8} {'[-]':>8} {'[-]':>8}")
        lines.append(f"{result.reference:>16} {'':>8} {'':>8} "
                     f"{result.breakage[0].hardin_bp0:>8.4f}")
        for b in result.breakage:
            lines.append(f"{b.label:>16} {b.marsal_members:>8.2f} {b.marsal_sieves:>8.2f} "
                         f"{b.hardin_bp:>8.4f} {b.hardin_bt:>8.4f} {b.hardin_br:>8.4f} "
                         f"{b.bbi_a:>8.4f} {b.bbi_b:>8.4f} {b.bbi:>8.4f}")
    else:
        lines.append("  (no record after the reference)")
    lines += [f"  note: {note}" for note in result.notes]
    lines += bond_lines(records)

    labels = [r.label for r in records]
    width = max(10, *(len(label) for label in labels))
    n_all = np.unique(np.concatenate([r.n_members for r in records]))
    lines += ["", "% passing by member count n (mass in fragments of <= n spheres):",
              f"{'n':>6} " + " ".join(f"{label:>{width}}" for label in labels)]
    table = [passing(r.n_members, r.mass, n_all) for r in records]
    for i, n in enumerate(n_all):
        lines.append(f"{n:>6d} " + " ".join(f"{p[i] * PERCENT:>{width}.2f}" for p in table))
    lines += ["", "% passing by sieve aperture a [mm] (mass with d <= a):",
              f"{'a':>8} " + " ".join(f"{label:>{width}}" for label in labels)]
    table = [passing(result.diameter(r), r.mass, result.sieves) for r in records]
    for i, a in enumerate(result.sieves):
        lines.append(f"{a * MM:>8.3f} " + " ".join(f"{p[i] * PERCENT:>{width}.2f}"
                                                   for p in table))
    return lines


def bond_lines(records) -> list[str]:
    """The intact bonds of the records that hold them (the track's), and how many broke since
    the record before."""
    held = [r for r in records if r.n_bonds is not None]
    if not held:
        return []
    lines = ["", "intact bonds per record (and broken since the record before):",
             f"{'record':>16} {'bonds':>10} {'broken':>10}"]
    before = None
    for r in held:
        broken = "" if before is None else f"{before - r.n_bonds:>10d}"
        lines.append(f"{r.label:>16} {r.n_bonds:>10d} {broken}")
        before = r.n_bonds
    return lines


def grading_dict(result: GradingAnalysis) -> dict:
    """The report as JSON-ready data [SI, fractions]."""
    fr = result.fragments
    curves = {}
    for r in fr.records:
        n, pn = grading_curve(r.n_members, r.mass)
        d, pd = grading_curve(result.diameter(r), r.mass)
        curves[r.label] = {"n": n.astype(int).tolist(), "passing_n": _floats(pn),
                           "d": _floats(d), "passing_d": _floats(pd),
                           "passing_sieves": _floats(passing(result.diameter(r), r.mass,
                                                             result.sieves))}
    return {
        "file": str(fr.results.path), "kind": fr.results.kind,
        "density": fr.density, "member_radius_min": fr.member_radius_min,
        "d_min": result.d_min, "intact_members": result.intact_members,
        "sieves": _floats(result.sieves), "reference": result.reference,
        "units": {"time": "s", "mass": "kg", "d": "m", "d50": "m", "d_max": "m",
                  "d_min": "m", "sieves": "m", "density": "kg/m^3", "member_radius_min": "m",
                  "fractions": "-", "marsal": "%", "hardin": "-", "bbi": "-"},
        "records": [{k: _json(v) for k, v in asdict(s).items()} for s in result.summaries],
        "breakage": [{k: _json(v) for k, v in asdict(b).items()} for b in result.breakage],
        "curves": curves,
        "notes": list(result.notes),
        **({"bonds": {r.label: r.n_bonds for r in fr.records if r.n_bonds is not None}}
           if any(r.n_bonds is not None for r in fr.records) else {}),
    }


def plot_grading(result: GradingAnalysis, path) -> Path:
    """Grading curves, one per record: % passing by member count and by sieve diameter."""
    from matplotlib.figure import Figure

    from .figures import save

    fig = Figure(figsize=(11.0, 4.8), layout="constrained")
    ax_n, ax_d = fig.subplots(1, 2)
    from matplotlib.ticker import LogLocator, StrMethodFormatter

    records = result.fragments.records
    colours = _colours(len(records))
    n_hi = 1.1 * max(r.n_members.max() for r in records)
    d_hi = 1.1 * max(result.diameter(r).max() for r in records)
    for r, colour in zip(records, colours):
        label = f"{r.label} (t = {r.time:.4g} s)"
        for ax, (x, p), lo, hi, scale in (
                (ax_n, grading_curve(r.n_members, r.mass), 1.0, n_hi, 1.0),
                (ax_d, grading_curve(result.diameter(r), r.mass), result.d_min, d_hi, MM)):
            # from 0 % at the smallest possible size to 100 % beyond the largest fragment
            xs = np.concatenate(([min(lo, x[0])], x, [hi])) * scale
            ax.step(xs, np.concatenate(([0.0], p, [1.0])) * PERCENT, where="post",
                    color=colour, label=label)
    ax_n.axvline(result.intact_members, color="0.5", ls=":", lw=1.0,
                 label=f"n = {result.intact_members} (intact grain)")
    ax_d.axvline(result.d_min * MM, color="0.5", ls=":", lw=1.0, label="one sphere (d_min)")
    for ax, xlabel in ((ax_n, "fragment size: member spheres n [-]"),
                       (ax_d, "sieve diameter d = (6m/πρ)^(1/3) [mm]")):
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(StrMethodFormatter("{x:g}"))
        ax.xaxis.set_minor_formatter(StrMethodFormatter(""))
        ax.set(xlabel=xlabel, ylabel="mass passing [%]", ylim=(-2, 102))
        ax.grid(True, which="both", alpha=0.3)
    ax_n.set_title("Grading by number of spheres")
    ax_d.set_title("Grading by sieve diameter")
    ax_n.legend(fontsize="small", loc="upper left")
    return save(fig, path)


def plot_breakage(result: GradingAnalysis, path) -> Path:
    """Breakage per record (e.g. per passage of a track): Hardin's B_r (= BBI here) and Marsal's
    B_g against the reference, the mass in intact grains and in single spheres, and, where the
    records hold them, the bonds broken since the first record."""
    from matplotlib.figure import Figure

    from .figures import save

    fig = Figure(figsize=(11.0, 4.4), layout="constrained")
    ax_i, ax_m = fig.subplots(1, 2)
    records = result.fragments.records
    x = np.arange(len(records))
    labels = [r.label for r in records]
    index = {b.label: b for b in result.breakage}
    nan = float("nan")
    br = [0.0 if r.label == result.reference else index[r.label].hardin_br if r.label in index else nan
          for r in records]
    bg = [0.0 if r.label == result.reference else index[r.label].marsal_sieves if r.label in index else nan
          for r in records]
    ax_i.plot(x, np.asarray(br) * PERCENT, "o-", label="Hardin B_r = BBI [%]")
    ax_i.plot(x, bg, "s--", label="Marsal B_g (sieves) [%]")
    ax_i.set(ylabel="breakage index [%]", title=f"Breakage against {result.reference!r}")
    s = result.summaries
    ax_m.plot(x, [v.fraction_intact * PERCENT for v in s], "o-", label="mass in intact grains")
    ax_m.plot(x, [v.fraction_single * PERCENT for v in s], "s--", label="mass in single spheres")
    ax_m.set(ylabel="mass [%]", title="Intact grains and single spheres")
    bonds = [r.n_bonds for r in records]
    if all(b is not None for b in bonds):
        ax_b = ax_m.twinx()
        ax_b.plot(x, [bonds[0] - b for b in bonds], "^:", color="C3", label="bonds broken since the first")
        ax_b.set_ylabel("bonds broken [-]", color="C3")
        ax_b.legend(fontsize="small", loc="center right")
    for ax in (ax_i, ax_m):
        ax.set_xticks(x, labels, rotation=45 if len(x) > 6 else 0, ha="right" if len(x) > 6 else "center",
                      fontsize="small")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small", loc="upper left")
    return save(fig, path)


def run_grading(run_or_file, out=None, reference=None, intact_members=INTACT_MEMBERS,
                sieves=None) -> list[Path]:
    """Analyse the fragment records of a run; write grading.png, grading.txt, grading.json and,
    with two records or more, breakage.png (the indices per record)."""
    path = results_file(run_or_file)
    result = analyse_grading(read_fragments(path), reference=reference,
                             intact_members=intact_members, sieves=sieves)
    out = Path(out) if out is not None else default_out(path)
    out.mkdir(parents=True, exist_ok=True)
    text, js = out / "grading.txt", out / "grading.json"
    text.write_text("\n".join(grading_lines(result)) + "\n")
    js.write_text(json.dumps(grading_dict(result), indent=1, allow_nan=False) + "\n")
    written = [plot_grading(result, out / "grading.png"), text, js]
    if len(result.fragments.records) >= 2:
        written.append(plot_breakage(result, out / "breakage.png"))
    return written


def add_parser(sub) -> None:
    """The ``grading`` subcommand of ``python -m analysis``."""
    p = sub.add_parser(
        "grading", help="clump breakage: grading curves and breakage indices",
        description="Write grading.png, grading.txt and grading.json from the /fragments "
                    "records of a run: grading curves, mass in single spheres and in "
                    "fragments of >= N spheres, Marsal B_g, Hardin B_r and BBI against the "
                    "first (or --reference) record; with two records or more breakage.png "
                    "(the indices per record, e.g. per passage of a track).")
    p.add_argument("results", type=Path, metavar="RUN_OR_FILE",
                   help="run directory (with results.h5) or results file")
    p.add_argument("--out", type=Path, metavar="DIR",
                   help="output directory (default: RUN/analysis of a run folder, else RESULTS-analysis)")
    p.add_argument("--reference", metavar="LABEL", help="reference record (default: first)")
    p.add_argument("--intact-members", type=int, default=INTACT_MEMBERS, metavar="N",
                   help="spheres of an intact grain (default: %(default)s, Nottingham)")
    p.add_argument("--sieves", type=_mm_list, metavar="MM,MM,...",
                   help="sieve apertures in mm (default: d_min * sqrt(2)^k)")
    p.set_defaults(run=lambda a: run_grading(a.results, a.out, a.reference, a.intact_members,
                                             a.sieves))


def _mm_list(text: str) -> np.ndarray:
    import argparse

    try:
        values = np.array([float(v) for v in text.split(",") if v.strip()]) / MM
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of mm") from None
    if len(values) < 1:
        raise argparse.ArgumentTypeError("no sieve given")
    return values


def _percent_by_class(classes, mass) -> dict:
    classes, mass = np.asarray(classes), np.asarray(mass, dtype=np.float64)
    keys, inverse = np.unique(classes, return_inverse=True)
    w = np.bincount(inverse.ravel(), weights=mass, minlength=len(keys))
    w = w / w.sum() * PERCENT
    return {k.item(): float(v) for k, v in zip(keys, w)}


def _passing_area(d, mass, lo: float, hi: float) -> float:
    """Integral of the passing fraction P(x) over log10 x from lo to hi (P is a step
    function, right-continuous: it jumps up at each fragment size)."""
    d = np.asarray(d, dtype=np.float64)
    inside = d[(d > lo) & (d < hi)]
    x = np.unique(np.concatenate(([lo, hi], inside)))
    p = passing(d, mass, x[:-1])
    return float(np.sum(p * np.diff(np.log10(x))))


def _colours(n):
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    return [cmap(0.9 * i / max(n - 1, 1)) for i in range(n)]


def _pct(x) -> str:
    return "-" if not math.isfinite(x) else f"{x * PERCENT:.2f}"


def _floats(values) -> list:
    return [_json(float(v)) for v in np.asarray(values, dtype=np.float64)]


def _json(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, np.generic):
        return value.item()
    return value
