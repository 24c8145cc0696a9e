"""The track section (SPEC.md 2.4, thesis ch. 6 and the multi-sleeper track it left for future
work): a ballast bed with shoulders and cribs under rigid sleepers, prepared once, then loaded
by a wheel-load cycle (the thesis's slice) or by trains of axles passing at a speed, on any
number of ranks (slabs cut across the track axis x).

Coordinates: x along the track (the slab axis), y across it (y = 0 the track's centre line),
z up (z = 0 the top of the subgrade). A scene file with a ``[track]`` table (keys, defaults
and units in `DEFAULTS`, `TRAFFIC_DEFAULTS`; SI) describes:

- ``sleepers`` rigid concrete sleepers (`pdem.bodies.boxes`: one body each, of mass ``sleeper_mass``
  [kg] (default ρV of the sleeper material) plus the rail over one ``spacing``,
  ``rail_mass`` [kg/m] per rail) of ``sleeper_size`` = [width along x, length across y,
  height] [m], at x_k = (k + ½)·spacing, their base at z = ``bed_depth``; translations not in
  ``sleeper_blocked`` free (default: z only; a half model: x and z, as the thesis's slice);
  by default they do not rotate. ``sleeper_rotation = true`` makes them turning boxes that tilt
  (default blocked "xyZ": z and the tilts about x and y; a half model "yXZ": x, z and the tilt
  about y, the only one its symmetry plane allows), with the inertia ``sleeper_inertia``
  [kg m²] (3 principal moments or a tensor) or that of the homogeneous box plus the rails as
  point masses at their seats (`sleeper_inertia`); the load acts at the rail seats
  (`seat_offsets`: with the beam each rail's pad at its seat, which moves with the sleeper).
  ``sleeper_surface = "spheres"`` gives each sleeper body the contact shape of a closed shell of
  member spheres of ``sleeper_member_radius`` [m] (`surface_settings`,
  `pdem.scenes.common.sleepers`; not with turning sleepers), ``sleeper_mass = "members"`` their
  mass (ρ Σ 4/3 π r³, Yade's clump mass).
- the bed: from the subgrade (wall z = 0, ``base_material``, soft: stands for the layers
  below) to the sleeper top z_top = bed_depth + sleeper height, over the whole track length
  L = sleepers·spacing between end walls x = 0 and x = L; the shoulders reach
  ``shoulder_width`` [m] beyond the sleeper ends at z_top and fall at 1:``slope`` to the toe;
  the slopes are retaining facets (two triangles per side, with a short vertical lip at the
  top), as in the thesis (its mould was 4 planes and 4 facets). ``half = true`` models the half
  on y >= 0 by symmetry (a wall at y = 0, sleeper y-translation blocked): the thesis's slice
  is ``half = true, sleepers = 1`` (600 mm of track, half-sleeper 1300 x 300 x 220 mm).
- the ballast: spheres (``radius``, ``radius_spread``), or with a ``[track.clumps]`` table clumps
  of one grain (`clump_settings`: the oedometer's keys, `pdem.scenes.common.grains`): rigid, or
  breakable (bonded members, law "cohesive"; ``bond_boost`` [-] holds the bonds that much
  stronger from the pour to the end of the refill). The cuts remove whole clumps.
- The rail: by default not a body (a rigid sleeper that cannot rotate carries the rail-seat
  load wherever it acts, so the rail adds only its mass); with ``[traffic] rail_model = "beam"``
  an elastic beam on pads over the sleepers (`pdem.boundaries.rail_beam.SleeperRails`, keys
  ``rail_pad_stiffness`` [N/m], ``rail_length`` [m]; `rail_settings`): each step the pads'
  forces, from the sleepers' positions and the wheels, are the sleepers' loads, and the rail's
  weight goes through the pads instead of the sleepers' mass.

Stages: the preparation pipeline shared with the box test (`pdem.scenes.common.preparation`), in
the thesis's order for the track (compact the bed, then cut it and place the sleeper on it):

1. ``pour``     a loose cloud fills the box x in [0, L], |y| <= y_toe (the toe of the slope)
                up to z_top (times the overfill); settle.
2. ``vibrate``  shake the box with friction lowered; restore.
3. ``settle``   settle.
4. ``refill``   cut the compacted bed to its shape: remove the spheres that stick out above
                z_top, beyond the slopes, or into a sleeper; place the sleepers in their slots
                (base at z = bed_depth) and the slope facets; settle. The end-of-stage
                checkpoint is copied to ``prepared.h5``: the prepared bed, which any number of
                load programs start from ([traffic] prepared = that file or its run directory)
                without preparing again.
   With ``procedure = "refill"`` (the thesis's order, 6.1: vibrate, cut at 350 mm, place the
   sleeper, refill, vibrate again, cut above the sleeper top) ``refill`` instead cuts the bed at
   bed_depth, places the sleepers, pours a loose cloud around them (`refill_areas`) and settles,
   with no slope facets yet; ``vibrate_again`` shakes as ``vibrate``; ``settle_again`` cuts
   the bed to its shape, places the slope facets and settles; its end is the prepared bed.
   ``stiffen``  (only with ``prep_stiffness_factor`` f < 1, law linear: stages 1-4 then ran with
                every material's young times f) the stiffness raised to the materials' over
                ``stiffen_time`` [s], settled (`pdem.scenes.common.stiffening`, the box test's
                stage); its end-of-stage checkpoint is then the prepared bed.
5. ``traffic``  (only with a ``[traffic]`` table) ``program = "axles"``: `pdem.boundaries.loads.AxleTrain`
                (``passages`` trains of axles at positions ``axles`` [m] behind the first,
                ``axle_load`` [N], ``speed`` [m/s]; each sleeper carries the time-shifted
                rail-seat share of every wheel, `pdem.boundaries.loads.rail_seat_share`, characteristic
                length L = (4 EI a / k_d)^(1/4) from ``rail_bending_stiffness`` EI [N m²] and
                ``rail_seat_stiffness`` k_d [N/m] or given as ``characteristic_length`` [m]);
                ``program = "haversine"``: ``cycles`` cycles ``f_min`` <-> ``f_max`` [N per rail
                seat] at ``frequency`` [Hz] on every sleeper, one passage per cycle (the
                thesis's 0 -> F -> 0). ``damping`` [-]: Cundall's λ_D of the ballast and the
                sleepers in this stage (default: ``simulation.damping``, the preparation's; a
                prepared bed takes any).

Results (`pdem.format.schema`, kind "track"): ``results.h5`` with /series (`TRACK_SERIES`), /track
(settlement and ballast force of every sleeper per sample), /passages (peak and permanent
settlement, gap under each sleeper; with the beam the peak load on each sleeper; turning sleepers:
settlement of each end, tilts, the void under each end third, with the beam the load share;
the energy ledger: the loads' work on the sleepers and the change of the mechanical energy),
/forces/peak_passage_<p> and end_passage_<p> (contact force distributions, passages 1, every
``forces_every``-th and the last); with breakable grains /fragments/prepared (when the traffic
starts) and /fragments/passage_<p> (the fragments and the intact bonds, `grading_record`); ``preparation.h5`` and
``.png``; ``analysis/`` (`python -m analysis track`); ``summary.txt`` (stages, passages, wall
time, throughput, load balance over the ranks, timing table) and ``scaling.json`` (the same,
for `bench.scaling_model`); ParaView snapshots (the spheres, walls and sleepers,
`pdem.driver.snapshots`) on schedule, at stage ends and at every recorded force distribution.
"""
import json
import os
import shutil
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..build.config import check_keys, run_settings, scene_from_dict
from ..driver import observables
from ..driver.fragments import FragmentRecorder
from ..driver.results import write_root_attrs
from ..driver.stages import Stage, empty_tables, next_free_gid, nothing, remove_above, scaled_stiffness
from ..errors import InputError
from ..io.checkpoint import CheckpointError, read_checkpoint
from ..boundaries.loads import ETA_ZERO, AxleTrain, Haversine, SleeperLoad
from ..boundaries.rail_beam import RailBeam, RailSection, SleeperRails
from ..build.validate import boolean, number
from .common.bounds import plausible
from .common.grains import grain_reach, grain_spec
from .common.sleepers import members_mass, sleeper_members
from ..bodies.boxes import principal_inertia
from .common.preparation import PREPARATION_DEFAULTS, PreparedRun, add_cloud, check_preparation, \
    pour_stage, refill_stage, remove_where, settle_stage, vibrate_stage
from .common.stiffening import STIFFEN_DEFAULTS, check_stiffening, soft, stiffen_stage
from .track_record import (PassageTracker, TrackWriter, end_heights, mechanical_energy, sleeper_sample, tilts,
                           write_force_record)

PREPARATION = ("pour", "vibrate", "settle", "refill")  # the pipeline's stages: compacted before the cut
STAGES = PREPARATION + ("traffic",)
TOP_TABLES = {"simulation", "run", "materials", "track", "traffic"}
# [track] keys and defaults (SPEC.md 2.4, thesis ch. 6 and table 6.1; stiffness is in [materials])
DEFAULTS = {
    "half": False,                      # model y >= 0 only (symmetry about the track's centre line)
    "sleepers": 6,                      # number of sleepers [-]
    "spacing": 0.6,                     # sleeper spacing [m] (thesis: 600 mm "u", 674.5 mm "c")
    "sleeper_size": [0.3, 2.6, 0.2],    # width (x), length (y), height (z) [m]: B91
    "rail_mass": 60.21,                 # [kg/m] per rail (UIC 60 / 60E1)
    "gauge": 1.435,                     # [m]
    "rail_head_width": 0.072,           # [m] (60E1): rail seats at y = ±(gauge + head)/2
    "rail_foot_width": 0.15,            # [m] (60E1): the seat must lie on the sleeper
    "bed_depth": 0.35,                  # ballast under the sleeper base [m] (thesis 6.1)
    "shoulder_width": 0.4,              # ballast beyond the sleeper end at the top [m]
    "slope": 1.5,                       # shoulder slope 1:slope (horizontal per vertical) [-]
    "ballast_material": "ballast", "wall_material": "steel", "base_material": "rubber",
    "sleeper_material": "concrete",
    "sleeper_surface": "flat",          # "flat": a smooth rigid box; "spheres": a closed shell of member spheres
    "sleeper_member_radius": 0.005,     # [m] of the "spheres" surface (`pdem.scenes.common.sleepers`)
    "procedure": "cut",                 # "cut": compacted to the top, slots cut; "refill": the thesis's 6.1 order
    **PREPARATION_DEFAULTS,
    # full stiffness: prepared at young x prep_stiffness_factor, then `stiffen` (`pdem.scenes.common.stiffening`)
    **STIFFEN_DEFAULTS,
}
OPTIONAL = {"sleeper_mass", "sleeper_blocked", "sleeper_rotation", "sleeper_inertia",
            "periodic",  # periodic: no ends along x (`periodic_settings`)
            "clumps",    # the ballast as clumps, rigid or breakable (`clump_settings`)
            "bond_boost"}  # breakable grains: bond strengths x this while the bed is prepared
SPHERE_KEYS = ("radius", "radius_spread")  # size sphere ballast only
TRAFFIC_DEFAULTS = {
    "program": "axles", "prepared": "", "forces_every": 0,
    # program "axles"
    "axle_load": 225e3,                 # [N] (22.5 t, UIC line category D)
    "axles": [0.0, 2.5],                # axle positions behind the first [m]: one bogie
    "speed": 27.78,                     # [m/s] (100 km/h)
    "passages": 1, "rest_time": 0.2,    # [-], unloaded time after each passage [s]
    "rail_bending_stiffness": 6.38e6,   # EI of one rail [N m^2] (60E1: E 210 GPa, I 3038 cm^4)
    "rail_seat_stiffness": 6.0e7,       # support stiffness per rail seat k_d [N/m]
    "rail_model": "share",              # "share": prescribed rail-seat shares; "beam": the rail as a beam on pads
    "rail_pad_stiffness": 1.0e8,        # [N/m] per rail pad (rail_model "beam"; 100 kN/mm)
    # program "haversine" (thesis ch. 6: 0 -> F -> 0; table 6.1: F = 200 kN)
    "f_min": 0.0, "f_max": 200e3, "frequency": 1.0, "cycles": 1,
}
TRAFFIC_OPTIONAL = {"x_from", "x_to", "characteristic_length", "rail_length", "damping"}
AXLE_KEYS = {"axle_load", "axles", "speed", "passages", "rest_time", "rail_bending_stiffness", "rail_seat_stiffness",
             "x_from", "x_to", "characteristic_length", "rail_model", "rail_pad_stiffness", "rail_length"}
BEAM_KEYS = {"rail_pad_stiffness", "rail_length"}  # rail_model "beam" only
RAIL_MODELS = ("share", "beam")
SURFACES = ("flat", "spheres")  # sleeper_surface
PROCEDURES = ("cut", "refill")  # procedure: how the sleepers are placed (`TrackRun.stage_list`)
TURNING = {False: "xyZ", True: "yXZ"}  # sleeper_rotation: blocked DOFs of a whole track, a half model
HAVERSINE_KEYS = {"f_min", "f_max", "frequency", "cycles"}
WHERE = ("track", "in the track bed")
PREPARED = "prepared.h5"


# ---------------------------------------------------------------------------- settings
def track_settings(doc):
    """The [track] table with defaults, checked (one-line InputError naming the key)."""
    given = doc["track"]
    check_keys("track", given, set(DEFAULTS) | OPTIONAL)
    for k in doc:
        if k not in TOP_TABLES:
            raise InputError(f"scene file.{k}: unknown table for a track scene; allowed: "
                             f"{', '.join(sorted(TOP_TABLES))}")
    c = {**DEFAULTS, **given}
    c["half"] = boolean("track.half", c["half"])
    v = c["sleeper_size"]
    if not (isinstance(v, list) and len(v) == 3):
        raise InputError(f"track.sleeper_size = {v!r}: must be [width x, length y, height z] > 0 [m]")
    c["sleeper_size"] = [number("track.sleeper_size", x, 0.0, lo_open=True, allow="[x, y, z] lengths > 0 [m]")
                         for x in v]
    for k in ("ballast_material", "wall_material", "base_material", "sleeper_material"):
        if not isinstance(c[k], str) or c[k] not in doc.get("materials", {}):
            raise InputError(f"track.{k} = {c[k]!r}: no [materials.{c[k]}] table in the scene file")
    check_preparation("track", c)
    if c["procedure"] not in PROCEDURES:
        raise InputError(f"track.procedure = {c['procedure']!r}: must be one of {', '.join(map(repr, PROCEDURES))} "
                         "('cut': the bed compacted to the sleeper top, the slots cut; 'refill': cut at the sleeper "
                         "base, sleepers placed, refilled, vibrated again, cut to shape: thesis 6.1)")
    c["grain"] = clump_settings(doc, given)
    c["bond_boost"] = bond_boost_settings(c, given)
    check_stiffening("track", c, doc)
    c["sleepers"] = number("track.sleepers", c["sleepers"], 1, integer=True)
    for k in ("spacing", "gauge", "rail_head_width", "rail_foot_width", "bed_depth", "slope"):
        c[k] = number(f"track.{k}", c[k], 0.0, lo_open=True)
    for k in ("rail_mass", "shoulder_width"):
        c[k] = number(f"track.{k}", c[k], 0.0)
    plausible("track", {k: v for k, v in c.items() if k not in ("sleeper_mass", "clumps", "grain")})
    w, length, h = c["sleeper_size"]
    if w >= c["spacing"]:
        raise InputError(f"track.sleeper_size = {c['sleeper_size']!r}: the sleeper width {w} m must be less than the "
                         f"spacing {c['spacing']} m")
    seat = (c["gauge"] + c["rail_head_width"]) / 2
    if seat + c["rail_foot_width"] / 2 > length / 2:
        raise InputError(f"track.sleeper_size = {c['sleeper_size']!r}: the rail seats at y = ±{seat:g} m (gauge "
                         f"{c['gauge']:g} m) lie beyond the sleeper ends at ±{length / 2:g} m: the wheel loads would "
                         "reach no sleeper")
    r_max = ballast_reach(c)
    if c["bed_depth"] < 2 * r_max:
        raise InputError(f"track.bed_depth = {c['bed_depth']!r}: must hold at least one grain (>= {2 * r_max:g} m)")
    density = number(f"materials.{c['sleeper_material']}.density",
                     doc["materials"][c["sleeper_material"]].get("density"), 0.0, lo_open=True,
                     allow="a finite number > 0 [kg/m³] (the sleepers' mass)")
    share = 0.5 if c["half"] else 1.0
    rotation = c["sleeper_rotation"] = boolean("track.sleeper_rotation", c.get("sleeper_rotation", False))
    surface_settings(doc, c, given)
    if given.get("sleeper_mass") == "members":  # the body's members; the whole sleeper's is 1/share of it
        c["sleeper_mass"] = members_mass(c["sleeper_members"], c["sleeper_member_radius"], float(density)) / share
    elif "sleeper_mass" in given:
        c["sleeper_mass"] = number("track.sleeper_mass", c["sleeper_mass"], 0.0, lo_open=True,
                                   allow="a mass > 0 [kg] or 'members' (with sleeper_surface = 'spheres')")
        plausible("track", {"sleeper_mass": c["sleeper_mass"]})
    else:
        c["sleeper_mass"] = float(density) * w * length * h
    c["body_mass"] = share * c["sleeper_mass"] + (1 if c["half"] else 2) * c["rail_mass"] * c["spacing"]
    blocked = c.get("sleeper_blocked", TURNING[c["half"]] if rotation else "yXYZ" if c["half"] else "xyXYZ")
    if rotation:
        need = "XZ" if c["half"] else "Z"
        why = "turning sleepers: the vertical axis blocked" + (
            "; a half model's symmetry plane y = 0 allows only the tilt about y" if c["half"] else "")
    else:
        need, why = "XYZ", "sleepers do not rotate; sleeper_rotation = true lets them tilt"
    if not isinstance(blocked, str) or set(blocked) - set("xyzXYZ") or not set(need) <= set(blocked):
        raise InputError(f"track.sleeper_blocked = {blocked!r}: must be letters from 'xyzXYZ' including "
                         f"{', '.join(need)} ({why})")
    if c["half"] and "y" not in blocked:
        raise InputError(f"track.sleeper_blocked = {blocked!r}: a half model needs 'y' (no translation across the "
                         "symmetry plane)")
    c["sleeper_blocked"] = blocked
    periodic_settings(doc, c)
    if "sleeper_inertia" in given and not rotation:
        raise InputError("track.sleeper_inertia: used only with sleeper_rotation = true; remove it")
    if rotation and "sleeper_inertia" in given:
        try:
            principal_inertia("track", c["sleeper_inertia"], 1.0, np.ones(3))
        except InputError:
            raise InputError(f"track.sleeper_inertia = {c['sleeper_inertia']!r}: must be 3 principal moments or a "
                             "3x3 tensor [kg m^2] of the sleeper body about its centre in its axes, symmetric "
                             "positive definite") from None
    if "steps" in doc.get("run", {}):
        raise InputError("run.steps: not used by a track scene (its stages end on their own criteria; "
                         "`pdem run --steps N` stops one early); remove it")
    return c


def surface_settings(doc, c, given):
    """``sleeper_surface`` "flat" (a smooth rigid box) or "spheres": each sleeper body's contact
    shape is the closed shell of member spheres of radius ``sleeper_member_radius`` [m] on the
    lattice of `pdem.scenes.common.sleepers.sleeper_members` over the body's box (a half model's
    half-sleeper; its end at the symmetry plane closed too), ``c["sleeper_members"]`` [k, 3]
    (None for "flat"); ``sleeper_mass = "members"`` (only with "spheres") gives the body the
    members' mass of the sleeper material's density. Refused: a member radius <= 0 or above a
    quarter of the body's smallest dimension (no shell), turning sleepers (a box with members
    cannot rotate, `pdem.bodies.boxes`), periodic ends (untested with member sleepers)."""
    surface = c["sleeper_surface"]
    if surface not in SURFACES:
        raise InputError(f"track.sleeper_surface = {surface!r}: must be one of {', '.join(map(repr, SURFACES))}")
    if surface == "flat":
        if given.get("sleeper_mass") == "members":
            raise InputError("track.sleeper_mass = 'members': needs sleeper_surface = 'spheres' (a flat sleeper has no "
                             "members); give a mass > 0 [kg] or leave it out (the sleeper material's density x volume)")
        if "sleeper_member_radius" in given:
            raise InputError(f"track.sleeper_member_radius = {given['sleeper_member_radius']!r}: used only with "
                             "sleeper_surface = 'spheres'; remove it")
        c["sleeper_members"] = None
        return
    size = 2.0 * sleeper_boxes(c)[1]
    r = c["sleeper_member_radius"] = number("track.sleeper_member_radius", c["sleeper_member_radius"], 0.0,
                                             lo_open=True, allow="a radius > 0 [m]")
    if r > size.min() / 4:
        raise InputError(f"track.sleeper_member_radius = {r!r}: at most a quarter of the sleeper body's smallest "
                         f"dimension ({size.min():g} m / 4 = {size.min() / 4:g} m), so that its members form a shell")
    n = np.round(size / (2 * r))
    if np.any(n * 2 * r > size * (1 + 1e-9)):
        raise InputError(f"track.sleeper_member_radius = {r!r}: its lattice of {n.astype(int).tolist()} spheres of "
                         f"diameter {2 * r:g} m sticks out of the sleeper body {size.tolist()} m; choose r with "
                         "round(size / 2r) 2r <= size on every axis")
    if c["sleeper_rotation"]:
        raise InputError("track.sleeper_surface = 'spheres': a sleeper of member spheres cannot rotate "
                         "(pdem.bodies.boxes); use sleeper_rotation = false or sleeper_surface = 'flat'")
    if given.get("periodic") is True:
        raise InputError("track.sleeper_surface = 'spheres': member sleepers with periodic ends are untested; use "
                         "periodic = false or sleeper_surface = 'flat'")
    c["sleeper_members"] = sleeper_members(size, r, closed=True)


def clump_settings(doc, given):
    """None for sphere ballast, else the grain of ``[track.clumps]`` (the keys of the oedometer's
    ``[oedometer.clumps]``: `pdem.scenes.common.grains.grain_spec`; rigid clumps, or breakable
    grains with ``breakable = true`` and the cohesive law). The spheres' ``radius`` and
    ``radius_spread`` are refused beside it (the grain's members size the ballast)."""
    if "clumps" not in given:
        return None
    for k in SPHERE_KEYS:
        if k in given:
            raise InputError(f"track.{k} = {given[k]!r}: sizes sphere ballast, but [track.clumps] gives the ballast as "
                             "clumps (their members size it); remove one of them")
    return grain_spec(doc, given["clumps"], "track.clumps")


def bond_boost_settings(c, given):
    """``bond_boost`` [-] (default 1): the breakable grains' bond strengths a_N, a_T times this from
    the start of the pour to the end of the preparation (the refill), returned when the traffic
    starts: the pour drops the grains from up to the cloud's top, and those impacts, which a
    placed ballast never sees, would break them (thesis 4.5 raised the bonds tenfold while its
    oedometer's grains settled). Only with breakable grains; > 0."""
    if "bond_boost" not in given:
        return 1.0
    g = c.get("grain")
    if g is None or not g["breakable"]:
        raise InputError(f"track.bond_boost = {given['bond_boost']!r}: scales bonds, which only breakable grains have "
                         "([track.clumps] breakable = true); remove it")
    return number("track.bond_boost", given["bond_boost"], 0.0, lo_open=True, allow="a factor > 0 [-]")


def ballast_reach(c):
    """The largest radius [m] of a ballast body: r (1 + spread) of the spheres, or the radius of the
    sphere holding a grain (`grain_reach`)."""
    return c["radius"] * (1 + c["radius_spread"]) if c.get("grain") is None else grain_reach(c["grain"])


def ballast_radius(c):
    """The ballast's nominal radius [m]: ``radius`` of the spheres, or a grain's reach (the speed
    scale sqrt(g r) of the sleepers' rest test)."""
    return c["radius"] if c.get("grain") is None else grain_reach(c["grain"])


def periodic_settings(doc, c):
    """``[track] periodic = true``: the track has no ends along x (the engine's periodic ends over
    [0, L], L = sleepers x spacing: no end walls, `pdem.parallel.periodic_domain`); checked."""
    if "periodic" not in c:
        return
    c["periodic"] = boolean("track.periodic", c["periodic"])
    if c["periodic"] and c.get("grain") is not None:
        raise InputError("track.periodic = true: the engine's periodic ends take spheres only, not the clumps of "
                         "[track.clumps] (rigid or breakable); remove one of them")
    sim = doc.get("simulation", {})
    if "periodic" in sim:
        raise InputError("simulation.periodic: set by track.periodic in a track scene; remove it")
    if c["periodic"] and sim.get("slab_axis", "x") != "x":
        raise InputError(f"simulation.slab_axis = {sim['slab_axis']!r}: track.periodic = true needs 'x' (the track "
                         "axis)")


def traffic_settings(doc, c):
    """The [traffic] table with defaults, checked; None if the file has none (prepare only)."""
    if "traffic" not in doc:
        return None
    given = doc["traffic"]
    check_keys("traffic", given, set(TRAFFIC_DEFAULTS) | TRAFFIC_OPTIONAL)
    t = {**TRAFFIC_DEFAULTS, **given}
    if t["program"] not in ("axles", "haversine"):
        raise InputError(f"traffic.program = {t['program']!r}: must be 'axles' or 'haversine'")
    other = HAVERSINE_KEYS if t["program"] == "axles" else AXLE_KEYS
    for k in sorted(other & set(given)):
        raise InputError(f"traffic.{k}: not used by program = {t['program']!r}; remove it")
    if not isinstance(t["prepared"], str):
        raise InputError(f"traffic.prepared = {t['prepared']!r}: must be the path of a prepared bed (a run "
                         f"directory or its {PREPARED})")
    t["forces_every"] = number("traffic.forces_every", t["forces_every"], 0, integer=True)
    if "damping" in given:
        t["damping"] = number("traffic.damping", given["damping"], 0.0, 0.99, allow="in [0, 0.99] (Cundall's lambda_D)")
    x = sleeper_x(c)
    if t["program"] == "haversine":
        t["passages"] = number("traffic.cycles", t["cycles"], 1, integer=True)
        Haversine(t["f_min"], t["f_max"], t["frequency"], t["cycles"], label="traffic")  # checks the values
        plausible("traffic", {k: t[k] for k in HAVERSINE_KEYS})
        return t
    for k in ("rail_bending_stiffness", "rail_seat_stiffness"):
        t[k] = number(f"traffic.{k}", t[k], 0.0, lo_open=True)
    if "characteristic_length" not in given:
        ei, kd = t["rail_bending_stiffness"], t["rail_seat_stiffness"]
        t["characteristic_length"] = (4.0 * ei * c["spacing"] / kd) ** 0.25
    length = number("traffic.characteristic_length", t["characteristic_length"], 0.0, lo_open=True)
    reach = ETA_ZERO * length
    if c.get("periodic"):  # every axle over one period: each sleeper sees it once per passage
        period_length = profile(c)["length"]
        t["x_from"] = number("traffic.x_from", t.get("x_from", 0.0))
        t["x_to"] = number("traffic.x_to", t.get("x_to", t["x_from"] + period_length))
        laps = (t["x_to"] - t["x_from"]) / period_length
        if not (laps >= 1.0 - 1e-9 and abs(laps - round(laps)) <= 1e-9):
            raise InputError(f"traffic.x_to = {t['x_to']!r}: with track.periodic = true an axle must run a whole "
                             f"number of periods from x_from = {t['x_from']!r} (x_to - x_from = k x {period_length:g} "
                             "m), else the sleepers near the ends see it more or less often than the others")
    t.setdefault("x_from", float(x[0] - reach))
    t.setdefault("x_to", float(x[-1] + reach))
    train = make_train(t, c, 0.0)
    if t["x_to"] <= x[0] - reach or t["x_from"] >= x[-1] + reach:
        raise InputError(f"traffic.x_from = {train.x_from!r}, x_to = {train.x_to!r}: the axles never come within "
                         f"reach ({reach:.3g} m = 3π/4 L) of a sleeper (x = {x[0]:g} .. {x[-1]:g} m): no axle load "
                         "reaches any sleeper")
    t = rail_settings(t, given, c, train)
    plausible("traffic", {k: t[k] for k in AXLE_KEYS if k in t})
    return t


def rail_settings(t, given, c, train):
    """The rail model's keys of [traffic] (program "axles"), checked: ``rail_model`` "share" (the
    prescribed shares) or "beam" (`pdem.boundaries.rail_beam`: ``rail_pad_stiffness`` [N/m] > 0,
    ``rail_length`` [m] at most the track's, centred on it); with the beam, the sleepers' mass
    ``body_mass`` leaves the rails out (their weight reaches the sleepers through the pads)."""
    if t["rail_model"] not in RAIL_MODELS:
        raise InputError(f"traffic.rail_model = {t['rail_model']!r}: must be 'share' (prescribed rail-seat shares) or "
                         "'beam' (the rail as a beam on pads)")
    t["body_mass"] = c["body_mass"]
    if t["rail_model"] == "share":
        for k in sorted(BEAM_KEYS & set(given)):
            raise InputError(f"traffic.{k}: not used by rail_model = 'share'; remove it")
        if c.get("periodic"):
            raise InputError("traffic.rail_model = 'share': its rail-seat shares end at the track's ends; "
                             "track.periodic = true needs rail_model = 'beam' (a periodic rail) for axles")
        return t
    t["rail_pad_stiffness"] = number("traffic.rail_pad_stiffness", t["rail_pad_stiffness"], 0.0, lo_open=True,
                                     allow="a number > 0 [N/m]")
    length = profile(c)["length"]
    t["rail_length"] = number("traffic.rail_length", t.get("rail_length", length), 0.0, lo_open=True,
                              allow="a length > 0 [m]")
    if t["rail_length"] > length:
        raise InputError(f"traffic.rail_length = {t['rail_length']!r}: longer than the track ({length:g} m = sleepers "
                         "x spacing, between the end walls)")
    if c.get("periodic") and t["rail_length"] != length:
        raise InputError(f"traffic.rail_length = {t['rail_length']!r}: track.periodic = true needs the rail over the "
                         f"whole period ({length:g} m = sleepers x spacing); remove it")
    rails = 1 if c["half"] else 2
    t["body_mass"] = c["body_mass"] - rails * c["rail_mass"] * c["spacing"]
    sleeper_rails(c, t, train)  # checks that the rail reaches over every seat
    return t


def sleeper_rails(c, t, train):
    """The rails of rail_model "beam" over the sleepers' seats (one per modelled rail), for ``train``."""
    x = sleeper_x(c)
    if len(x) < 2:
        raise InputError(f"track.sleepers = {c['sleepers']}: rail_model = 'beam' needs at least 2 sleepers (a rail "
                         "on one pad has no bending)")
    length, mid = t["rail_length"], profile(c)["length"] / 2
    section = RailSection(t["rail_bending_stiffness"], c["rail_mass"])
    ring = {"periodic": True} if c.get("periodic") else {}  # the rail's ends joined over the period
    beams = [RailBeam(x, t["rail_pad_stiffness"], section=section, x_start=mid - length / 2, x_end=mid + length / 2,
                      label="traffic.rail_length", **ring) for _ in range(1 if c["half"] else 2)]
    return SleeperRails(beams, train, seats=seat_offsets(c) if c["sleeper_rotation"] else None)


def check_pad_step(sim, t, rails, seats=None):
    """The pads act on the sleepers explicitly: the time step must resolve a sleeper on its
    ``rails`` pads (stiffness at most k each, `pdem.boundaries.rail_beam`): Δt <= sqrt(m / (rails
    k)), half the leapfrog's limit for safety; turning sleepers (``seats``: the pads' points, box
    axes [m]) also its rocking on them about every free tilt axis, Δt <= sqrt(I / (k Σ lever²));
    else a one-line InputError naming the key."""
    k = t["rail_pad_stiffness"]
    m = float(np.min(sim.boxes.mass))
    limit = (m / (rails * k)) ** 0.5
    what = f"a sleeper of {m:.4g} kg on {rails} pad(s) needs dt <= sqrt(m/(n k))"
    for axis, lever in ((0, None if seats is None else seats[:, 1]), (1, None if seats is None else seats[:, 0])):
        if lever is None or np.all(sim.boxes.blocked & (8 << axis)) or not np.any(lever):
            continue
        moment = float(np.min(sim.boxes.inertia[:, axis]))
        rocking = (moment / (k * float(np.sum(lever ** 2)))) ** 0.5
        if rocking < limit:
            limit, what = rocking, (f"a sleeper of {moment:.4g} kg m^2 about {'xy'[axis]} rocking on its pads needs "
                                    "dt <= sqrt(I/(k sum lever^2))")
    if sim.dt > limit:
        raise InputError(f"traffic.rail_pad_stiffness = {k!r}: too stiff for the time step {sim.dt:.3g} s ({what} = "
                         f"{limit:.3g} s)")


def make_train(t, c, start):
    return AxleTrain(t["axle_load"], t["axles"], t["speed"], t["passages"], spacing=c["spacing"],
                     length=t["characteristic_length"], x_from=t["x_from"], x_to=t["x_to"], rest_time=t["rest_time"],
                     start=start, label="traffic")


def check_ranks(c, doc, size):
    """A track shorter than ``size`` slabs of one halo each: one-line InputError."""
    if c.get("grain") is None:
        r_max, r_mean = c["radius"] * (1 + c["radius_spread"]), c["radius"]
    else:  # the slabs hold member spheres (a clump's on the rank of its centre)
        r_max, r_mean = float(np.max(c["grain"]["member_radii"])), float(np.mean(c["grain"]["member_radii"]))
    skin = doc.get("simulation", {}).get("skin", 0.25 * r_mean)
    halo = 2 * r_max + float(skin)
    length = c["sleepers"] * c["spacing"]
    if size > 1 and length - 2 * r_max < size * halo:
        most = max(int((length - 2 * r_max) // halo), 1)
        raise InputError(f"track.sleepers = {c['sleepers']}: a track of {length:g} m is shorter than {size} slabs "
                         f"allow (each at least one halo, 2 r_max + skin = {halo:.4g} m, thick): use at most "
                         f"{most} rank(s) or a longer track")


# ---------------------------------------------------------------------------- geometry
def sleeper_x(c):
    """x of every sleeper's centre [m]."""
    return (np.arange(c["sleepers"]) + 0.5) * c["spacing"]


def profile(c):
    """The bed's cross-section: z_top (sleeper top = shoulder top), y_top (shoulder edge),
    y_toe (foot of the slope), y_lo (lowest y of the model: 0 or -y_toe) [m]."""
    w, length, h = c["sleeper_size"]
    z_top = c["bed_depth"] + h
    y_top = length / 2 + c["shoulder_width"]
    y_toe = y_top + c["slope"] * z_top
    return {"z_top": z_top, "y_top": y_top, "y_toe": y_toe, "y_lo": 0.0 if c["half"] else -y_toe,
            "length": c["sleepers"] * c["spacing"]}


def sleeper_boxes(c):
    """(centres [n, 3], half extents [3]) of the sleepers resting at z = bed_depth."""
    w, length, h = c["sleeper_size"]
    yc, hy = (length / 4, length / 4) if c["half"] else (0.0, length / 2)
    x = sleeper_x(c)
    centres = np.stack([x, np.full(len(x), yc), np.full(len(x), c["bed_depth"] + h / 2)], axis=1)
    return centres, np.array([w / 2, hy, h / 2])


def seat_offsets(c):
    """[n_rails, 3] the rail seat of every modelled rail (a half model one, a whole track two: y
    = ∓(gauge + head)/2) on the sleeper body, in its axes from its centre [m]: on its top face."""
    centres, half = sleeper_boxes(c)
    seat = (c["gauge"] + c["rail_head_width"]) / 2
    return np.array([[0.0, y - centres[0, 1], half[2]] for y in ((seat,) if c["half"] else (-seat, seat))])


def sleeper_inertia(c, rails):
    """Principal moments [3] [kg m²] of a turning sleeper body about its centre, in its axes:
    ``sleeper_inertia`` if given, else the homogeneous box of the body's sleeper mass (a half
    model's half) plus, if ``rails``, each rail over one spacing as a point mass at its seat's
    y at the centre's height (the body's centre of mass stays its centre; the rail's own
    moments are left out)."""
    if "sleeper_inertia" in c:
        return c["sleeper_inertia"]
    half = sleeper_boxes(c)[1]
    a2, b2, c2 = (2.0 * half) ** 2
    m = (0.5 if c["half"] else 1.0) * c["sleeper_mass"]
    moments = m / 12.0 * np.array([b2 + c2, a2 + c2, a2 + b2])
    if rails:
        mr = c["rail_mass"] * c["spacing"]
        for dy in seat_offsets(c)[:, 1]:
            moments += mr * dy * dy * np.array([1.0, 0.0, 1.0])
    return moments.tolist()


def outside_bed(c, pos, r):
    """True for the spheres not wholly inside the bed's cross-section: above z_top or beyond a
    slope (signed distance to the slope plane > -r)."""
    g = profile(c)
    z_top, y_top = g["z_top"], g["y_top"]
    dy = g["y_toe"] - y_top
    norm = np.hypot(z_top, dy)
    y = np.abs(pos[:, 1])
    s = ((y - y_top) * z_top + (pos[:, 2] - z_top) * dy) / norm
    return (pos[:, 2] + r > z_top) | (s > -r)


def in_sleepers(c, pos, r):
    """True for the spheres that overlap a sleeper (distance to its box < r)."""
    centres, half = sleeper_boxes(c)
    hit = np.zeros(len(pos), bool)
    for ctr in centres:
        e = np.maximum(np.abs(pos - ctr) - half, 0.0)
        hit |= np.einsum("ij,ij->i", e, e) < r * r
    return hit


def refill_areas(c):
    """Rectangles (lo_xy, hi_xy) [m] that procedure "refill" pours into over the bed cut at
    bed_depth, around the placed sleepers: the cribs between them (and at the track's ends) over
    the whole width y_lo .. y_toe, and beyond each sleeper end to the toe."""
    g = profile(c)
    w, length, _ = c["sleeper_size"]
    x = sleeper_x(c)
    edges = [0.0, *[e for xk in x for e in (xk - w / 2, xk + w / 2)], g["length"]]
    out = [((a, g["y_lo"]), (b, g["y_toe"])) for a, b in zip(edges[::2], edges[1::2]) if b > a]
    for xk in x:
        out.append(((xk - w / 2, length / 2), (xk + w / 2, g["y_toe"])))
        if not c["half"]:
            out.append(((xk - w / 2, -g["y_toe"]), (xk + w / 2, -length / 2)))
    return out


def slope_facets(c):
    """Triangles (3 vertices each) of the slopes and their vertical lips, on each modelled side."""
    g = profile(c)
    L, z_top, y_top, y_toe = g["length"], g["z_top"], g["y_top"], g["y_toe"]
    lip = z_top + 4 * ballast_reach(c)
    out = []
    for s in ((1.0,) if c["half"] else (1.0, -1.0)):
        quads = [((0, s * y_toe, 0), (L, s * y_toe, 0), (L, s * y_top, z_top), (0, s * y_top, z_top)),
                 ((0, s * y_top, z_top), (L, s * y_top, z_top), (L, s * y_top, lip), (0, s * y_top, lip))]
        for a, b, cc, d in quads:
            out += [(a, b, cc), (a, cc, d)]
    return out


# ---------------------------------------------------------------------------- stage scenes
def stage_scene(doc, c, tables, sleepers=True, loads=None, centres=None, mass=None, rails=True, stiffness=1.0,
                slopes=True):
    """The `Scene` of a stage holding the spheres of ``tables``: the file's materials and
    settings, the subgrade, end and side walls, and if ``sleepers`` (from ``refill`` on) the
    slope facets (unless not ``slopes``: procedure "refill" before its last cut) and the
    sleepers (at ``centres`` if given; loaded by ``loads`` in ``traffic``; each of ``mass``
    [kg], default the track's ``body_mass``; turning sleepers with the inertia of
    `sleeper_inertia`, the rails' point masses in it if ``rails``, and the load at the mean of
    their rail seats). Every material's stiffness times ``stiffness`` (``prep_stiffness_factor``
    before ``traffic``)."""
    base = {k: v for k, v in doc.items() if k in ("simulation", "materials")}
    if stiffness != 1.0:
        base["materials"] = scaled_stiffness(base["materials"], stiffness)
    base["simulation"] = {"slab_axis": "x", **base.get("simulation", {}), "allow_initial_overlap": True}
    g = profile(c)
    if c.get("periodic"):  # no ends: periodic over [0, L] instead of the end walls
        base["simulation"]["periodic"] = [0.0, g["length"]]
    scene = scene_from_dict(base)
    wm = c["wall_material"]
    scene.add_wall("z", 0.0, c["base_material"], sense=1, name="subgrade")
    if not c.get("periodic"):
        scene.add_wall("x", 0.0, wm, sense=1, name="x_min")
        scene.add_wall("x", g["length"], wm, sense=-1, name="x_max")
    scene.add_wall("y", g["y_lo"], wm, sense=1, name="symmetry" if c["half"] else "y_min")
    scene.add_wall("y", g["y_toe"], wm, sense=-1, name="y_max")
    if sleepers:
        for k, tri in enumerate(slope_facets(c) if slopes else ()):
            scene.add_facet(tri, wm, name=f"slope_{k}")
        start, half = sleeper_boxes(c)
        at = start if centres is None else np.asarray(centres, float)
        turning = {"inertia": sleeper_inertia(c, rails), "load_point": seat_offsets(c).mean(axis=0)} \
            if c["sleeper_rotation"] else {}
        if c["sleeper_members"] is not None:  # sleeper_surface "spheres"
            turning = {"members": c["sleeper_members"], "member_radius": c["sleeper_member_radius"]}
        for k in range(c["sleepers"]):
            scene.add_box(at[k], half, c["sleeper_material"], c["body_mass"] if mass is None else mass,
                          blocked=c["sleeper_blocked"],
                          load=None if loads is None else loads[k], damping=scene.settings.damping,
                          name=f"sleeper_{k}", **turning)
    scene.add_sphere_columns(tables["particles"])
    if "clumps" in tables:  # rigid clumps (breakable grains: their bonds come with the contacts)
        scene.add_clump_tables(tables["clumps"], tables["clump_members"])
    return scene


def traffic_loads(c, t, start):
    """The load program of every sleeper for traffic ``t`` starting at ``start`` [s], and the
    passages' nominal (ends, peak instants) [s]."""
    wheels = 1 if c["half"] else 2
    x = sleeper_x(c)
    if t["program"] == "haversine":
        prog = Haversine(wheels * t["f_min"], wheels * t["f_max"], t["frequency"], t["cycles"], start=start,
                         label="traffic")
        n = t["cycles"]
        ends = [start + (p + 1) / t["frequency"] for p in range(n)]
        peaks = [start + (p + 0.5) / t["frequency"] for p in range(n)]
        return [prog] * len(x), ends, peaks
    train = make_train(t, c, start)
    mid = 0.5 * (x[0] + x[-1])
    ends = [train.passage_times(p)[1] for p in range(train.passages)]
    peaks = [train.time_over(p, mid) for p in range(train.passages)]
    rail = sleeper_rails(c, t, train) if t["rail_model"] == "beam" else None
    return [train.sleeper_load(xk, wheels, rail) for xk in x], ends, peaks


# ---------------------------------------------------------------------------- the run
def check(doc):
    """Check a parsed track scene file without running it (one-line InputError)."""
    c = track_settings(doc)
    t = traffic_settings(doc, c)
    run_settings(doc)
    loads = traffic_loads(c, t, 0.0)[0] if t is not None else None
    stage_scene(doc, c, empty_tables(), loads=loads, mass=None if t is None else t.get("body_mass"),
                rails=t is None or t.get("rail_model") != "beam")


def run(path, doc, out_dir, comm, steps=None, fresh=False):
    """Run (or resume) the track section of a parsed scene file; returns the exit status."""
    c = track_settings(doc)
    check_ranks(c, doc, comm.size)
    tr = TrackRun(path, doc, out_dir, comm, fresh)
    if steps is not None:
        tr.stop_step = number("--steps", steps, 0, integer=True)
    return tr.run()


def same_preparation(prep_doc, doc):
    """None if the two scene files prepare the same bed, else 'table.key = a there, b here'."""
    for table in ("simulation", "materials", "track"):
        a, b = prep_doc.get(table, {}), doc.get(table, {})
        for k in sorted(set(a) | set(b)):
            if a.get(k) != b.get(k):
                there, here = (repr(d[k]) if k in d else "(absent)" for d in (a, b))
                return f"{table}.{k} = {there} there, {here} here"
    return None


class TrackRun(PreparedRun):
    """One track section on this process's ranks: the shared preparation pipeline, the traffic
    stage and its records. ``state`` adds the traffic start, the passage tracker and where a
    prepared bed came from."""

    NAME = "track"

    def __init__(self, path, doc, out_dir, comm, fresh):
        self.c = track_settings(doc)
        self.t = traffic_settings(doc, self.c)
        self.tracker, self.writer, self.loads_report, self.rails = None, None, None, None
        self.snapped = None  # the step of the last snapshot written with a force record
        super().__init__(path, doc, out_dir, comm, fresh)
        self.step0 = int(self.meta["step"]) if self.meta else 0  # where this invocation starts
        self.rebuilds0 = int(self.meta.get("n_rebuilds", 0)) if self.meta else 0

    def stage_list(self):
        """`PREPARATION` (compacted before the cut; with ``procedure = "refill"`` its refill stage
        replaced by refill, vibrate_again, settle_again), ``stiffen`` if prepared soft
        (``prep_stiffness_factor`` < 1; the prepared bed saved after the last of these), then
        ``traffic`` if a [traffic] table is given."""
        bed = self.bed_scene
        pour = pour_stage(self, bed, self.pour, at_rest=self.bodies_settled)
        boost = self.c["bond_boost"] != 1.0
        stages = [pour.then(prepare=self.boost_bonds) if boost else pour,
                  vibrate_stage(self, bed),
                  settle_stage(self, bed, at_rest=self.bodies_settled)]
        if self.c["procedure"] == "cut":
            stages.append(refill_stage(self, self.stage_scene, self.refill, at_rest=self.bodies_settled))
        else:  # "refill" (thesis 6.1): no slopes until the last cut
            stages += [refill_stage(self, self.open_scene, self.refill_around, at_rest=self.bodies_settled),
                       vibrate_stage(self, self.open_scene, name="vibrate_again"),
                       settle_stage(self, self.stage_scene, "settle_again", open=self.cut_to_shape,
                                    at_rest=self.bodies_settled)]
        if soft(self.c):  # prepared soft: brought to the materials' stiffness before the traffic
            stages.append(stiffen_stage(self, self.stage_scene, at_rest=self.bodies_settled))
        stages[-1] = replace(stages[-1], saved=self.save_prepared_bed)
        if self.t is not None:
            stages.append(Stage("traffic", self.traffic_scene, self.load_program, open=self.open_traffic,
                                prepare=self.release_bonds if boost else nothing,
                                close=lambda sim: self.stage_done(sim, "traffic"), record=self.stage_record))
        return stages

    def boost_bonds(self, sim, scene, mid_stage):
        """At the start of the pour: the bond strengths times ``bond_boost`` (`bond_boost_settings`)."""
        if not mid_stage:
            sim.scale_bond_strength(self.c["bond_boost"])
            self.loop.log(f"bond strengths x {self.c['bond_boost']:g} until the traffic starts (track.bond_boost)")

    def release_bonds(self, sim, scene, mid_stage):
        """At the start of the traffic: the bonds back to their strength (c r^2 of the material)."""
        if not mid_stage:
            sim.scale_bond_strength(1.0 / self.c["bond_boost"])
            self.loop.log(f"bond strengths returned (/ {self.c['bond_boost']:g}) at t = {sim.time:.4g} s")

    def initial_state(self):
        state = {"traffic_start": None, "tracker": None, "prepared_from": None, "forces": [], "bonds": []}
        if soft(self.c):
            state["stiffness_scale"] = self.c["prep_stiffness_factor"]
        return state

    def checkpoint_state(self):
        return {**self.state, "tracker": self.tracker.state() if self.tracker else None}

    def start_point(self):
        """The prepared bed of [traffic] prepared, if given."""
        if self.t is None or not self.t["prepared"]:
            return None
        path = Path(self.t["prepared"])
        if path.is_dir():
            path = path / PREPARED
        if not path.is_file():
            raise InputError(f"traffic.prepared = {self.t['prepared']!r}: no prepared bed there (a run directory with "
                             f"{PREPARED}, or the file)")
        try:
            tables, meta = read_checkpoint(path)
        except CheckpointError as exc:
            raise InputError(f"traffic.prepared = {self.t['prepared']!r}: {exc}") from None
        state = meta.get(self.NAME)
        if not state or state.get("stage") != self.STAGES.index("traffic") or state.get("started"):
            raise InputError(f"traffic.prepared = {self.t['prepared']!r}: not a prepared bed of a track scene (the "
                             "checkpoint at the end of its preparation)")
        diff = same_preparation(tomllib.loads(meta["scene_file"]), self.doc)
        if diff is not None:
            raise InputError(f"traffic.prepared = {self.t['prepared']!r}: prepared from another scene ({diff})")
        state = {**state, "prepared_from": str(path), "traffic_start": None, "tracker": None, "forces": [],
                 "bonds": []}
        self.loop.log(f"starting from the prepared bed {path} (step {meta['step']}, t = {meta['time']:.6e} s, "
                      f"{len(tables['particles']['gid'])} spheres)")
        return tables, meta, state

    # ------------------------------------------------------------------ outputs
    def open_outputs(self):
        if self.state["prepared_from"] is None:
            super().open_outputs()
        else:  # no preparation here: its record is in the prepared run's directory
            self.prep = None
            self.open_results()

    def open_results(self):
        self.results = self.out / "results.h5"

    def close_outputs(self):
        if self.prep is not None:
            self.prep.close()
        if self.writer is not None:
            self.writer.close()

    # ------------------------------------------------------------------ preparation of the bed
    def pour(self, tables):
        c = self.c
        g = profile(c)
        tables = add_cloud(empty_tables(), self.doc, c, (0.0, g["y_lo"]), (g["length"], g["y_toe"]), 0.0,
                           g["length"] * (g["y_toe"] - g["y_lo"]) * g["z_top"], c["seed"], 0, WHERE)
        n = len(tables["particles"]["gid"])
        if c["grain"] is None:
            return tables, f"poured {n} spheres"
        k = len(c["grain"]["member_radii"])
        return tables, (f"poured {n // k} {'breakable' if c['grain']['breakable'] else 'rigid'} clumps of {k} "
                        f"spheres ({n} spheres)")

    def refill(self, tables):
        c = self.c
        tables, cut = remove_where(tables, lambda pos, r: outside_bed(c, pos, r))
        tables, slots = remove_where(tables, lambda pos, r: in_sleepers(c, pos, r))
        whole = "" if c["grain"] is None else ", whole clumps"
        return tables, (f"cut the bed to its shape ({cut} spheres above z_top = {profile(c)['z_top']:g} m or beyond "
                        f"the slopes{whole}), cleared {c['sleepers']} sleeper slot(s) ({slots} spheres), placed the "
                        "sleepers and the slope facets")

    def refill_around(self, tables):
        """Procedure "refill" (thesis 6.1: „Po uklidnění simulace jsou odstraněna zrna nad úrovní
        350 mm a je přidán železobetonový pražec … Následně je model dosypán dalším kamenivem“):
        the bed cut at bed_depth, the sleepers placed on it, a loose cloud poured around them
        (`refill_areas`, up to z_top times the overfill)."""
        c, doc = self.c, self.doc
        tables, cut = remove_above(tables, c["bed_depth"])
        n0 = len(tables["particles"]["gid"])
        rise = profile(c)["z_top"] - c["bed_depth"]
        gid = self.state["next_gid"]  # (the cut's gids are not reused)
        for k, (lo, hi) in enumerate(refill_areas(c)):
            tables = add_cloud(tables, doc, c, lo, hi, c["bed_depth"], (hi[0] - lo[0]) * (hi[1] - lo[1]) * rise,
                               c["seed"] + 1000 + k, gid, WHERE)
            gid = next_free_gid(tables, gid)
        what = "spheres" if c["grain"] is None else "spheres (whole clumps)"
        return tables, (f"cut the bed at bed_depth = {c['bed_depth']:g} m ({cut} {what}), placed the sleepers, "
                        f"poured {len(tables['particles']['gid']) - n0} spheres around them")

    def cut_to_shape(self, tables):
        """Procedure "refill", after the second vibration (thesis 6.1: „Po opětovném zvibrování je
        odstraněno kamenivo nad horní úrovní pražce“): the bed cut to its shape and the slope
        facets placed."""
        tables, cut = remove_where(tables, lambda pos, r: outside_bed(self.c, pos, r))
        return tables, (f"cut the bed to its shape ({cut} spheres above z_top = {profile(self.c)['z_top']:g} m or "
                        "beyond the slopes), placed the slope facets")

    def open_scene(self, tables):
        """Procedure "refill" before its last cut: the sleepers, no slope facets yet."""
        return self.stage_scene(tables, slopes=False)

    def bed_scene(self, tables):
        """The scene before the cut: no sleepers yet (at the preparation's stiffness)."""
        return stage_scene(self.doc, self.c, tables, sleepers=False, stiffness=self.c["prep_stiffness_factor"])

    def stage_scene(self, tables, loads=None, slopes=True):
        """The scene with the sleepers, at the preparation's stiffness (refill, stiffen)."""
        centres = tables["boxes"]["center"] if "boxes" in tables else None
        return stage_scene(self.doc, self.c, tables, loads=loads, centres=centres,
                           stiffness=self.c["prep_stiffness_factor"], slopes=slopes)

    def traffic_scene(self, tables):
        """The scene with the sleepers under the load program (λ_D ``traffic.damping`` if given)."""
        loads = traffic_loads(self.c, self.t, self.state["traffic_start"])[0]
        centres = tables["boxes"]["center"] if "boxes" in tables else None
        doc = self.doc
        if "damping" in self.t:
            doc = {**doc, "simulation": {**doc.get("simulation", {}), "damping": self.t["damping"]}}
        return stage_scene(doc, self.c, tables, loads=loads, centres=centres, mass=self.t.get("body_mass"),
                           rails=self.t.get("rail_model") != "beam")

    def bodies_settled(self, sim):
        """The sleepers at rest: on every one, |net force| / weight and |velocity| / sqrt(g r)
        below settle_ratio (a sleeper dropped into its slot bounces on the bed at ~10 Hz, which
        the spheres' ratio does not see)."""
        f, v = self.sleeper_rest(sim)
        return f < self.c["settle_ratio"] and v < self.c["settle_ratio"]

    def sleeper_rest(self, sim):
        """(largest |net force| / weight, largest |velocity| / sqrt(g r)) of the sleepers
        (`pdem.driver.observables.box_rest`, r the ballast's nominal radius)."""
        return observables.box_rest(sim, (float(np.linalg.norm(sim.gravity)) * ballast_radius(self.c)) ** 0.5)

    def bodies_note(self, sim):
        if sim.boxes is None:
            return ""
        base = sim.boxes.center[:, 2] - sim.boxes.half[:, 2]
        f, v = self.sleeper_rest(sim)
        return (f", sleeper centre z {1e3 * self.sleeper_z(sim):.1f} mm (mean; bottoms {1e3 * base.min():.1f} .. "
                f"{1e3 * base.max():.1f} mm; net force/weight {f:.2g}, "
                f"speed/sqrt(gr) {v:.2g})")

    def save_prepared_bed(self, written):
        """The prepared bed: a copy of the checkpoint at the end of the preparation."""
        if self.comm.rank == 0:
            tmp = self.out / (PREPARED + ".tmp")
            shutil.copyfile(written, tmp)
            os.replace(tmp, self.out / PREPARED)
            self.loop.log(f"prepared bed: {self.out / PREPARED} (start load programs from it with "
                          f"[traffic] prepared = \"{self.out}\")")
        self.comm.barrier()

    # ------------------------------------------------------------------ traffic
    def open_traffic(self, tables):
        self.state["traffic_start"] = float(self.meta["time"]) if self.meta else 0.0
        return tables, f"traffic: {self.traffic_text()}"

    def traffic_text(self):
        t = self.t
        damped = f"; damping {t['damping']:g} (traffic.damping)" if "damping" in t else ""
        if t["program"] == "haversine":
            return (f"{t['cycles']} cycle(s) {t['f_min']:g} <-> {t['f_max']:g} N per rail seat at "
                    f"{t['frequency']:g} Hz on every sleeper{damped}")
        rail = (f"rail-seat shares with L = {t['characteristic_length']:.4f} m" if t["rail_model"] == "share" else
                f"the rail as a beam (EI {t['rail_bending_stiffness']:.4g} N m^2, {self.c['rail_mass']:g} kg/m, "
                f"{t['rail_length']:g} m) on pads of {t['rail_pad_stiffness']:.4g} N/m")
        return (f"{t['passages']} passage(s) of {len(t['axles'])} axle(s) of {t['axle_load']:g} N at "
                f"{t['speed']:g} m/s, axles at {t['axles']} m, from x = {t['x_from']:.3f} to {t['x_to']:.3f} m, "
                f"rest {t['rest_time']:g} s; {rail}{damped}")

    def load_program(self, sim, scene):
        state, run = self.state, self.run_cfg
        t0 = state["traffic_start"]
        _, ends, peaks = traffic_loads(self.c, self.t, t0)
        resumed = state["tracker"] is not None
        load = sim.boxes.loads[0]  # the built simulation's own copy of the load programs
        self.rails = load.rail if isinstance(load, SleeperLoad) else None
        if resumed:
            tr = PassageTracker.restore(state["tracker"])
        else:
            tr = PassageTracker(ends, peaks, sim.boxes.center[:, 2], loads=self.rails is not None)
            tr.start(sim.time, tr.settlement(sim.boxes.center[:, 2]))
        self.tracker = tr
        turning = self.c["sleeper_rotation"]
        if turning and not resumed:  # where the sleepers' ends and seats were when the traffic started
            state["end_reference"] = end_heights(sim.boxes).tolist()
            state["seat_reference"] = None if self.rails is None else \
                self.rails.seat_heights(sim.boxes.center, sim.boxes.rotation).tolist()
            state["load_rest"] = None
        if self.rails is not None:
            # the rails laid on the sleepers (their seats, if the sleepers turn) where the traffic started
            self.rails.attach(sim.boxes, state["seat_reference"] if turning else tr.reference)
            check_pad_step(sim, self.t, len(self.rails.beams), self.rails.seats)
        self.writer = w = TrackWriter(self.results, sleeper_x(self.c), self.comm,
                                      restart_step=self.restart_step if resumed else None, passages_done=tr.p)
        self.loop.flush.append(w)
        if self.comm.rank == 0 and not resumed:
            write_root_attrs(self.results, {k: self.doc[k] for k in ("simulation", "materials", "track", "traffic")},
                             "track")
        frag = self.fragment_recorder()
        if frag is not None and not resumed:  # the grading of the prepared bed
            self.grading_record(sim, frag, "prepared")
        first = None if resumed else sim.step + 1  # the first row: after the first step (forces computed)
        n = len(ends)
        every = self.t["forces_every"]

        def recorded(p):  # passages (1-based) with force distributions
            return p == 1 or p == n or (every > 0 and p % every == 0)

        def on_step(sim):
            s = tr.settlement(sim.boxes.center[:, 2])
            load = None if self.rails is None else -sim.boxes.load_force[:, 2]
            if turning and load is not None and state["load_rest"] is None:
                state["load_rest"] = load.tolist()  # the first step of the traffic: no wheel on the rails
            events = tr.update(sim.time, s, load)
            tr.account(sim)
            p = tr.p + 1
            if "peak" in events and recorded(p):
                self.force_record(f"peak_passage_{p}", sim)
            if "end" in events:
                gap = observables.box_gaps(sim)
                row = tr.close(sim.time, s, mechanical_energy(sim))
                w.append(*sleeper_sample(sim, tr))
                more = self.turning_record(sim, row[4], load) if turning else {}
                w.passage(row[0], row[1], row[2], row[3], gap, load_peak=row[4], **row[5], **more)
                if more:
                    self.loop.log(f"passage {p}/{n}: tilt about x {1e3 * more['tilt_x'].min():.3f} .. "
                                  f"{1e3 * more['tilt_x'].max():.3f} mrad, about y {1e3 * more['tilt_y'].min():.3f}"
                                  f" .. {1e3 * more['tilt_y'].max():.3f} mrad; end gaps max "
                                  f"{1e3 * max(more['gap_lo'].max(), more['gap_hi'].max()):.3f} mm")
                if recorded(p):
                    self.force_record(f"end_passage_{p}", sim)
                if frag is not None:
                    self.grading_record(sim, frag, f"passage_{p}")
                self.loop.log(f"passage {p}/{n} done at t = {sim.time:.4f} s: settlement peak "
                              f"{1e3 * row[2].mean():.3f} (max {1e3 * row[2].max():.3f}) mm, permanent "
                              f"{1e3 * row[3].mean():.3f} ({1e3 * row[3].min():.3f} .. {1e3 * row[3].max():.3f}) mm, "
                              f"gap max {1e3 * gap.max():.3f} mm")
            elif sim.step == first or (run["output_every"] and sim.step % run["output_every"] == 0):
                w.append(*sleeper_sample(sim, tr))
            if frag is not None:
                frag.on_step(sim)
            self.snapshot(sim)

        return on_step, lambda sim: tr.done, 1, ends[-1]

    def fragment_recorder(self):
        """The fragment records of breakable grains (`FragmentRecorder`, also every
        run.fragments_every steps); None for spheres and rigid clumps (nothing breaks)."""
        g = self.c["grain"]
        if g is None or not g["breakable"]:
            return None
        return FragmentRecorder(self.results, self.comm, every=self.run_cfg["fragments_every"], bonds=True)

    def grading_record(self, sim, frag, label):
        """``/fragments/<label>`` (collective; "prepared" when the traffic starts, "passage_<p>" at
        the end of passage p) and the log line: intact bonds, bonds broken since the record
        before, fragments and the mass in intact grains. ``state["bonds"]`` keeps the intact bonds
        of every record (a resumed run logs the same)."""
        f = frag.record(sim, label)
        n_bonds = self.comm.allreduce_sum_int(f["n_bonds"] if f is not None else 0)
        done = self.state["bonds"]
        broken = "" if not done else f", {done[-1] - n_bonds} broken since the record before"
        done.append(n_bonds)
        if f is not None:
            k = len(self.c["grain"]["member_radii"])
            intact = float(f["mass"][f["n_members"] == k].sum() / f["mass"].sum())
            self.loop.log(f"grading {label}: {n_bonds} intact bonds{broken}; {len(f['mass'])} fragments, "
                          f"{100 * intact:.2f} % of the mass in whole grains, "
                          f"{100 * float(f['mass'][f['n_members'] == 1].sum() / f['mass'].sum()):.2f} % in single "
                          "spheres")

    def turning_record(self, sim, load_peak, load):
        """The /passages tables of turning sleepers at the end of a passage (collective): settlement
        of each end of every sleeper body (lo, hi along its y axis; from its height when the
        traffic started, positive down) [m], tilt about x and y [rad], the void under each end
        third (`observables.box_end_gaps`) [m]; with the beam the load share [-]: the largest
        load of the rails on the sleeper in the passage less its load at rest (the rails' weight:
        no wheel on them, the first step of the traffic or the end of the passage before),
        divided by the wheel loads on its rail seats (axle load / 2 per modelled rail). The load
        at rest is then this step's (the passage is over: no wheel on the rails)."""
        bx, state = sim.boxes, self.state
        settled = np.asarray(state["end_reference"]) - end_heights(bx)
        tilt = tilts(bx)
        gaps = observables.box_end_gaps(sim)
        out = {"settlement_lo": settled[:, 0], "settlement_hi": settled[:, 1], "tilt_x": tilt[:, 0],
               "tilt_y": tilt[:, 1], "gap_lo": gaps[:, 0], "gap_hi": gaps[:, 1]}
        if load_peak is not None:
            wheels = len(self.rails.beams) * self.t["axle_load"] / 2.0
            out["load_share"] = (np.asarray(load_peak) - np.asarray(state["load_rest"])) / wheels
            state["load_rest"] = load.tolist()
        return out

    def force_record(self, label, sim):
        write_force_record(self.results, label, sim)
        if self.snaps is not None and self.snapped != sim.step:
            self.write_snapshot(sim)
            self.snapped = sim.step
        self.state["forces"].append(label)

    def snapshot(self, sim, stage_end=False):
        if self.snapped != sim.step:  # not twice at one step (a force record and the schedule)
            super().snapshot(sim, stage_end)

    def stage_record(self, sim):
        return {**super().stage_record(sim), "balance": observables.rank_loads(sim)["imbalance"]}

    # ------------------------------------------------------------------ end of the run
    def collect(self, sim):
        self.loads_report = observables.rank_loads(sim)
        t = sim.timers.seconds
        self.timers_max = {k: self.comm.allreduce_max(float(v)) for k, v in t.items()}
        self.timers_total_max = self.comm.allreduce_max(float(sum(t.values())))
        self.n_bodies = self.comm.allreduce_sum_int(sim.particles.n_local)

    def scaling_record(self, sim, wall_s):
        """What `bench.scaling_model --scene track` reads: sizes, timings and the load balance."""
        g = profile(self.c)
        steps = sim.step - self.step0
        return {"scene": "track", "ranks": self.comm.size, "bodies": self.n_bodies, "steps": steps,
                "rebuilds": sim.n_rebuilds - self.rebuilds0, "wall_s": wall_s, "spacing": self.c["spacing"],
                "track_length": g["length"], "sleepers": self.c["sleepers"],
                "bodies_per_metre": self.n_bodies / g["length"], **sphere_size(self.c), "timers_max_s": self.timers_max,
                "timers_total_max_s": self.timers_total_max, "loads": self.loads_report,
                "uptime": _load_average()}

    def write_scaling(self, sim, wall_s):
        rec = self.scaling_record(sim, wall_s)
        (self.out / "scaling.json").write_text(json.dumps(rec, indent=1) + "\n")
        return rec

    def report_stop(self, sim, wall_s):
        rec = self.write_scaling(sim, wall_s)
        lines = balance_lines(rec) + ["", sim.timing_table()]
        (self.out / "summary.txt").write_text("\n".join(lines) + "\n")
        print("\n".join(lines), flush=True)

    def finish(self, sim, wall_s):
        """Rank 0 at the end: scaling.json and the run's account (with the track's description, the
        load balance and the traffic) for `python -m analysis summary`."""
        c, g, prepared = self.c, profile(self.c), self.state["prepared_from"]
        about = [f"{'half (y >= 0), ' if c['half'] else ''}{c['sleepers']} sleeper(s) {c['sleeper_size']} m at "
                 f"{c['spacing']} m, bed depth {c['bed_depth']} m, shoulder {c['shoulder_width']} m, slope "
                 f"1:{c['slope']}; track {g['length']:g} m x {g['y_toe'] - g['y_lo']:.3f} m at the toe; sleeper body "
                 f"{c['body_mass']:.1f} kg"] + ([f"prepared bed: {prepared}"] if prepared else [])
        traffic = self.t is not None and (self.out / "results.h5").exists()
        super().finish(sim, wall_s, summary="track", title="track section", about=about,
                       stage_columns=[("sleeper_z", "sleeper centre z [m]", ".4f"), ("balance", "balance", ".3f")],
                       preparation=None if prepared else {"stages": [s for s in self.STAGES if s != "traffic"],
                                                        "body": "sleeper centre"},
                       notes=balance_lines(self.write_scaling(sim, wall_s))
                       + (["", f"traffic: {self.traffic_text()}"] if traffic else []),
                       traffic=traffic)


def sphere_size(c):
    """{"radius", "radius_spread"} of the spheres the slabs hold [m, -]: the ballast's, or a grain's
    members (their largest radius, spread 0)."""
    if c.get("grain") is None:
        return {"radius": c["radius"], "radius_spread": c["radius_spread"]}
    return {"radius": float(np.max(c["grain"]["member_radii"])), "radius_spread": 0.0}


def _load_average():
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def balance_lines(rec):
    ld = rec["loads"]
    rate = rec["bodies"] * rec["steps"] / rec["wall_s"] if rec["wall_s"] > 0 else 0.0
    lines = [f"ranks: {rec['ranks']}, bodies: {rec['bodies']}, steps in this run: {rec['steps']}, wall time "
             f"{rec['wall_s']:.1f} s ({1e3 * rec['wall_s'] / max(rec['steps'], 1):.2f} ms/step), throughput "
             f"{rate / 1e6:.3f} M body-steps/s; load average {rec['uptime']}",
             f"load balance (work = owned bodies + their contact ends): max/mean {ld['imbalance']:.3f}; slab edges "
             f"{['%.3f' % e for e in ld['edges']] if ld['edges'] else '-'} m, halo {ld['halo'] * 1e3:.1f} mm, "
             f"{ld['rebalanced']} edge move(s), {ld['migrated']} migration(s)",
             "rank    owned   ghosts  contacts      work"]
    for r in range(rec["ranks"]):
        lines.append(f"{r:4d} {ld['owned'][r]:8d} {ld['ghosts'][r]:8d} {ld['contacts'][r]:9d} {ld['work'][r]:9.0f}")
    return lines
