"""Plausible ranges of the keys of the [track], [traffic], [blast] and [oedometer] sections, and
the check that refuses a value outside them naming a likely unit slip.

The type and sign checks of a key (`pdem.build.validate.number`) accept any positive number; a
sleeper 2600 m long (meant: mm) or a wheel load of 200 N (meant: kN) would then run, for hours,
into nonsense. `BOUNDS` gives, per section, key -> (low, high, unit, why): the range a railway
(or a scaled test of one) can have, wide enough for every shipped job and test scene and narrow
enough that a value 1000 times too large or too small falls outside. `plausible` checks a
section's checked settings against it (after the type checks, so the value is a finite number);
a value outside raises one `InputError` line naming the field, the value, the range and, when
the value times or divided by 1000 lies inside, the unit it was likely given in.
Units: SI, as in the scene files ([m], [N], [kg], [s], ...).
"""
from ...errors import InputError

# unit -> (its thousandth, its thousandfold): the names of the likely slips
SLIPS = {"m": ("mm", "km"), "N": ("mN", "kN"), "kg": ("g", "t"), "kg/m": ("g/m", "t/m"), "kg/m^2": ("g/m^2", "t/m^2"),
         "s": ("ms", "ks"), "m/s": ("mm/s", "km/s"), "N/m": ("N/km", "kN/m"), "N m^2": ("N mm^2", "kN m^2"),
         "Hz": ("mHz", "kHz"), "m/s^2": ("mm/s^2", "km/s^2")}

# the shared preparation of a ballast bed (pdem.scenes.common.preparation): its keys in every scene's table
PREPARATION_BOUNDS = {
    "radius": (1e-4, 0.5, "m", "ballast grain radius: 11-32 mm; shipped scenes 16-25 mm"),
    "overfill": (0.5, 10.0, "-", "poured volume / bed volume: 1-1.3 in the shipped scenes"),
    "packing_fraction": (0.01, 0.74, "-", "solid fraction: 0.25-0.6, at most 0.74 (the densest packing of spheres)"),
    "settle_min_time": (0.0, 1e3, "s", "simulated seconds: 0.05-0.2 s in the shipped scenes"),
    "settle_max_time": (0.0, 1e3, "s", "simulated seconds: 0.3-3 s in the shipped scenes (about 1e5 steps each)"),
    "vibration_time": (0.0, 1e3, "s", "simulated seconds of shaking: 0-0.5 s in the shipped scenes"),
    "vibration_frequency": (0.0, 1e3, "Hz", "the mould's shaking: 10 Hz in the shipped scenes"),
    "vibration_acceleration": (0.0, 1e3, "m/s^2", "the mould's shaking: 5 m/s^2 in the shipped scenes"),
}
BOUNDS = {
    "track": {
        "spacing": (0.05, 5.0, "m", "sleeper spacing: 0.6 m on main lines, 0.3 m in the scaled tests"),
        "sleeper_size": (0.01, 10.0, "m", "sleeper width, length, height: B91 0.3 x 2.6 x 0.2 m"),
        "gauge": (0.1, 5.0, "m", "track gauge: 1.435 m standard, 1 m metre gauge"),
        "rail_head_width": (0.005, 1.0, "m", "rail head: 72 mm (60E1)"),
        "rail_foot_width": (0.005, 1.0, "m", "rail foot: 150 mm (60E1)"),
        "bed_depth": (0.01, 5.0, "m", "ballast under the sleeper: 0.35 m (thesis 6.1)"),
        "shoulder_width": (0.0, 5.0, "m", "ballast shoulder: 0.4 m"),
        "slope": (0.1, 10.0, "-", "shoulder slope 1:1.5"),
        "rail_mass": (0.0, 500.0, "kg/m", "rail mass per length: 60.21 kg/m (UIC 60)"),
        "sleeper_mass": (0.01, 1e4, "kg", "a concrete sleeper: about 300 kg"),
    },
    "traffic": {
        "axle_load": (1e3, 2e6, "N", "a railway axle: 225 kN = 22.5 t (UIC D); scaled tests 1-20 kN"),
        "axles": (0.0, 1e3, "m", "axle positions behind the first: a bogie 2.5 m, a train up to hundreds of m"),
        "speed": (0.01, 150.0, "m/s", "train speed: 100 km/h = 27.78 m/s, 300 km/h = 83 m/s"),
        "rest_time": (0.0, 100.0, "s", "unloaded time after a passage: 0.05-0.2 s in the shipped scenes"),
        "rail_bending_stiffness": (1e3, 1e9, "N m^2", "EI of one rail: 6.38e6 N m^2 (60E1)"),
        "rail_seat_stiffness": (1e5, 1e10, "N/m", "support stiffness per rail seat: 6e7 N/m"),
        "rail_pad_stiffness": (1e4, 1e11, "N/m", "rail pad: 100 kN/mm = 1e8 N/m"),
        "rail_length": (0.01, 1e3, "m", "the modelled rail: the track's length"),
        "characteristic_length": (0.01, 100.0, "m", "the rail's characteristic length: about 0.8 m"),
        "f_min": (0.0, 2e6, "N", "the sleeper load's minimum"),
        "f_max": (1e3, 2e6, "N", "the sleeper load: 200 kN (thesis table 6.1)"),
        "frequency": (0.01, 1e3, "Hz", "load cycles: 1 Hz"),
    },
    "blast": {
        "box": (0.005, 10.0, "m", "the layer: 0.3 x 0.3 x 0.3 m (the paper), 0.06 m in CI"),
        "diameter_min": (1e-4, 0.5, "m", "grain diameter: 9-10 mm"),
        "diameter_max": (1e-4, 0.5, "m", "grain diameter: 9-10 mm"),
        "plates": (1.0, 1e6, "kg/m^2", "cover plates: 244-10780 kg/m^2"),
        "overfill": (0.5, 10.0, "-", "cloud volume / layer volume: 1.1"),
        "packing_fraction": (0.01, 0.74, "-", "solid fraction: 0.6, at most 0.74 (the densest packing of spheres)"),
        "plate_thickness": (1e-3, 1.0, "m", "cover plate: 20 mm"),
        "plate_lowering_speed": (0.0, 10.0, "m/s", "0.1 m/s"),
        "plate_settle_velocity": (0.0, 1.0, "m/s", "1 mm/s"),
        "F0": (1e3, 1e10, "N", "the impulse's peak: 9 MN (the paper)"),
        "tau": (1e-7, 0.05, "s", "the impulse's duration: 0.1 ms"),
        "duration": (1e-6, 10.0, "s", "simulated after the impulse: 9 ms"),
        "settle_min_time": (0.0, 1e3, "s", "simulated seconds: 0.05 s"),
        "settle_max_time": (0.0, 1e3, "s", "simulated seconds: 1 s"),
        "plate_settle_min_time": (0.0, 1e3, "s", "simulated seconds: 0.02 s"),
        "plate_settle_max_time": (0.0, 1e3, "s", "simulated seconds: 0.2 s"),
    },
    "oedometer": {
        "diameter": (0.01, 5.0, "m", "the cylinder: 300 mm (thesis), 90-180 mm scaled"),
        "facets": (6, 1000, "-", "flat facets around the cylinder wall: 24"),
        "height": (0.005, 5.0, "m", "the sample: 150 mm (thesis)"),
        "platen_thickness": (1e-3, 1.0, "m", "the platen: 10-20 mm"),
        "platen_mass": (1e-3, 1e4, "kg", "the platen: 0.5-11 kg"),
        "f_min": (0.0, 1e8, "N", "the load's minimum: 250 N (thesis)"),
        "f_max": (0.0, 1e8, "N", "the load's peak: 1.5 MN (thesis), 150 N in CI"),
        "load_time": (1e-4, 1e3, "s", "the load cycle: 0.1-2 s"),
    },
}


def plausible(section, c, bounds=None):
    """Raise a one-line InputError for the first key of ``c`` (a section's checked settings,
    numbers already finite) outside its range in ``bounds`` (default ``BOUNDS[section]``); list
    values are checked element by element."""
    for key, (lo, hi, unit, why) in (BOUNDS[section] if bounds is None else bounds).items():
        if key not in c:
            continue
        values = c[key] if isinstance(c[key], (list, tuple)) else [c[key]]
        for k, v in enumerate(values):
            if not lo <= v <= hi:
                label = f"{section}.{key}" + (f"[{k}]" if isinstance(c[key], (list, tuple)) else "")
                raise InputError(f"{label} = {v!r}: outside the plausible range {lo:g} .. {hi:g} {unit} ({why})"
                                 f"{slip(v, lo, hi, unit)}")


def slip(value, lo, hi, unit):
    """``"; V unit would be plausible: given in mm?"`` if ``value`` is a unit off by 1000, else ''."""
    small, large = SLIPS.get(unit, (None, None))
    for factor, name in ((1e-3, small), (1e3, large)):
        if name is not None and lo <= value * factor <= hi and value != 0:
            return f"; {value * factor:g} {unit} would be plausible: was it given in {name}?"
    return ""
