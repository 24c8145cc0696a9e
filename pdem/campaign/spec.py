"""Campaign files: parsing and expansion into members (pure: reads files, writes nothing).

A campaign file (TOML) names a base scene file and what varies; `expand` turns it into a list
of `Member` s, each with a name, the parameters that make it differ from the others and its
resolved scene document. Any scene key can vary, named by its dotted path (``box_test.seed``,
``materials.ballast.young``, ``walls.0.velocity``: an integer picks an element of an array of
tables). Tables of the campaign file:

    [campaign]  name (default: the file's stem), base (scene file, relative to the campaign
                file), out (default runs/<name>, relative to the working directory), ranks (MPI
                ranks per member, default 1), threads (numba threads per rank, default 1)
    [set]       keys applied to every member
    [seeds]     key (default box_test.seed or deposition.seed), values = [...] or count (and
                first, default 1): one member per seed
    [[grid]]    key = [values...] for each varied key; the keys are crossed, or zipped with
                zip = true (equal lengths)
    [[case]]    an explicit setting: name, the keys it sets, optional ranks and threads
    [local]     cores (of this machine used by ``pdem campaign run``; default: all it may use)
    [slurm]     time, partition, account, qos, signal_lead [s], max_running, launcher
                ("mpiexec": the venv's, the default | "srun"), launcher_args, options (extra sbatch options)
    [analysis]  defaults of ``python -m analysis campaign`` / ``error-vs-runtime``: quantities,
                curves, reference (copied to the manifest, not read here)

Cases, grids and seeds are crossed, in that order (seeds vary fastest). Keys may be written
quoted (``"materials.ballast.young" = [...]``) or as nested tables; both mean the same path.
Every member's scene is checked with `pdem.campaign.validate.check_member`: an unknown key or a
bad value stops the expansion with one line naming the member and the key. Imports no engine
module (the check is delegated).
"""
import itertools
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..build.config import deepcopy_doc as _deepcopy, load_toml, set_path  # noqa: F401 (set_path: API)
from ..errors import InputError
from .validate import check_member

CAMPAIGN_KEYS = {"name", "base", "out", "ranks", "threads"}
SEEDS_KEYS = {"key", "values", "count", "first"}
LOCAL_KEYS = {"cores"}
SLURM_KEYS = {"time", "partition", "account", "qos", "signal_lead", "max_running", "launcher", "launcher_args",
              "options", "job_name"}
TOP_KEYS = {"campaign", "set", "seeds", "grid", "case", "local", "slurm", "analysis"}
LAUNCHERS = ("srun", "mpiexec")
SLURM_DEFAULTS = {"time": "24:00:00", "partition": "", "account": "", "qos": "", "signal_lead": 300,
                  "max_running": 0, "launcher": "mpiexec", "launcher_args": [], "options": [], "job_name": ""}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+=-]*$")


@dataclass
class Member:
    """One run of a campaign: ``params`` (dotted key -> value, plus ``case`` if the campaign has
    cases) is what distinguishes it; ``overrides`` all keys set on the base; ``doc`` the scene."""

    name: str
    params: dict
    overrides: dict
    doc: dict
    ranks: int
    threads: int


@dataclass
class Campaign:
    """A parsed campaign file (paths absolute except ``out``, which is as given)."""

    path: Path
    name: str
    base: Path
    base_text: str             # the base as written in the campaign file
    out: Path
    ranks: int
    threads: int
    set: dict
    factors: list             # list of (kind, [level, ...]); a level is (label parts, overrides, extra)
    seed_key: str | None
    varied: list               # dotted keys that vary (grid and seeds), in factor order
    has_cases: bool
    cores: int | None
    slurm: dict
    analysis: dict
    members: list = field(default_factory=list)


def _err(path, msg):
    return InputError(f"{path}: {msg}")


def _check_keys(path, where, table, allowed):
    if not isinstance(table, dict):
        raise _err(path, f"[{where}] must be a table")
    for k in table:
        if k not in allowed:
            raise _err(path, f"{where}.{k}: unknown key; allowed: {', '.join(sorted(allowed))}")


def flatten(table, prefix=""):
    """{dotted path: leaf value} of a (nested) table; quoted dotted keys and nested tables mix."""
    out = {}
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        else:
            out[key] = v
    return out


def value_label(v):
    """A short, file-name-safe text of a parameter value (2.8e+06 -> 2.8e6)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        plain = f"{v:.10g}"
        if not math.isfinite(v):
            return plain
        mant, exp = f"{v:.10e}".split("e")
        mant = mant.rstrip("0").rstrip(".")
        sci = f"{mant}e{int(exp)}"
        return sci if len(sci) < len(plain) else plain
    if isinstance(v, (list, tuple)):
        return "x".join(value_label(x) for x in v)
    return re.sub(r"[^A-Za-z0-9.+-]+", "-", str(v)).strip("-") or "x"


def short_names(keys):
    """The shortest dotted suffix of each key that tells it from the others."""
    out = {}
    for k in keys:
        parts = k.split(".")
        for n in range(1, len(parts) + 1):
            suffix = ".".join(parts[-n:])
            if all(o == k or not (o == suffix or o.endswith("." + suffix)) for o in keys):
                break
        out[k] = suffix
    return out


def _int_width(values):
    ints = [v for v in values if isinstance(v, int) and not isinstance(v, bool) and v >= 0]
    return max((len(str(v)) for v in ints), default=0) if len(ints) == len(values) else 0


def _positive_int(path, where, v, lo=1):
    if not isinstance(v, int) or isinstance(v, bool) or v < lo:
        raise _err(path, f"{where} = {v!r}: must be an integer >= {lo}")
    return v


def load_campaign(path, out=None):
    """Parse and check a campaign file and expand it (members checked). ``out`` overrides
    [campaign] out. Raises InputError with one line."""
    path = Path(path)
    raw = load_toml(path, "campaign file")
    _check_keys(path, "campaign file", raw, TOP_KEYS)
    head = raw.get("campaign", {})
    _check_keys(path, "campaign", head, CAMPAIGN_KEYS)
    if "base" not in head:
        raise _err(path, "campaign.base: required key is missing (the base scene file)")
    name = head.get("name", path.stem)
    if not isinstance(name, str) or not _NAME.match(name):
        raise _err(path, f"campaign.name = {name!r}: must be letters, digits, and _ . + = - (no spaces or /)")
    for key in ("base", "out"):
        if key in head and not (isinstance(head[key], str) and head[key].strip()):
            raise _err(path, f"campaign.{key} = {head[key]!r}: must be a path (a non-empty string)")
    base = (path.parent / head["base"]).resolve() if not Path(head["base"]).is_absolute() else Path(head["base"])
    try:
        base_doc = load_toml(base, "base scene file")
    except InputError as exc:
        raise _err(path, f"campaign.base = {head['base']!r}: {exc}") from None
    ranks = _positive_int(path, "campaign.ranks", head.get("ranks", 1))
    threads = _positive_int(path, "campaign.threads", head.get("threads", 1))
    out_dir = Path(out) if out is not None else Path(head.get("out", str(Path("runs") / name)))

    common = raw.get("set", {})
    if not isinstance(common, dict):
        raise _err(path, "[set] must be a table")
    common = flatten(common)

    factors, varied, seed_key = [], [], None
    cases = _list_of_tables(path, raw, "case")
    if cases:
        levels, names = [], set()
        for k, c in enumerate(cases):
            cname = c.get("name", f"case{k + 1}")
            if not isinstance(cname, str) or not _NAME.match(cname):
                raise _err(path, f"case[{k}].name = {cname!r}: must be letters, digits, and _ . + = -")
            if cname in names:
                raise _err(path, f"case[{k}].name = {cname!r}: used by two cases")
            names.add(cname)
            extra = {}
            for r in ("ranks", "threads"):
                if r in c:
                    extra[r] = _positive_int(path, f"case[{k}].{r}", c[r])
            sets = flatten({a: b for a, b in c.items() if a not in ("name", "ranks", "threads")})
            levels.append(([cname], sets, {"case": cname, **extra}))
        factors.append(("case", levels))
    for g, grid in enumerate(_list_of_tables(path, raw, "grid")):
        zipped = grid.get("zip", False)
        if not isinstance(zipped, bool):
            raise _err(path, f"grid[{g}].zip = {zipped!r}: must be true or false")
        keys = flatten({a: b for a, b in grid.items() if a != "zip"})
        if not keys:
            raise _err(path, f"grid[{g}]: empty grid (no key to vary)")
        for key, values in keys.items():
            if not isinstance(values, list) or not values:
                raise _err(path, f"grid[{g}].{key} = {values!r}: must be a non-empty list of values")
            if key in varied:
                raise _err(path, f"grid[{g}].{key}: varied twice")
            if not zipped:
                _no_repeats(path, f"grid[{g}].{key}", values, "value")
            varied.append(key)
        if zipped:
            lengths = {k: len(v) for k, v in keys.items()}
            if len(set(lengths.values())) > 1:
                raise _err(path, f"grid[{g}]: zip = true needs lists of equal length, got "
                                 + ", ".join(f"{k}: {n}" for k, n in lengths.items()))
            n = next(iter(lengths.values()))
            _no_repeats(path, f"grid[{g}] (zip = true)", [[v[i] for v in keys.values()] for i in range(n)], "row")
            factors.append(("zip", [(None, {k: v[i] for k, v in keys.items()}, {}) for i in range(n)]))
        else:
            for key, values in keys.items():
                factors.append(("grid", [(None, {key: v}, {}) for v in values]))
    seeds = raw.get("seeds")
    if seeds is not None:
        _check_keys(path, "seeds", seeds, SEEDS_KEYS)
        seed_key = seeds.get("key")
        if seed_key is None:
            seed_key = ("box_test.seed" if "box_test" in base_doc else "deposition.seed" if "deposition" in base_doc
                        else None)
            if seed_key is None:
                raise _err(path, "seeds.key: required (the base scene has no [box_test] or [deposition] table)")
        elif not isinstance(seed_key, str) or not seed_key:
            raise _err(path, f"seeds.key = {seed_key!r}: must be a dotted scene key as text, e.g. \"oedometer.seed\"")
        if "values" in seeds and "count" in seeds:
            raise _err(path, "seeds: give either values or count (and first), not both")
        if "values" in seeds:
            values = seeds["values"]
            if not isinstance(values, list) or not values:
                raise _err(path, f"seeds.values = {values!r}: must be a non-empty list of integers")
            for v in values:
                _positive_int(path, "seeds.values[]", v, lo=0)
            if len(set(values)) != len(values):
                raise _err(path, f"seeds.values = {values!r}: a seed is repeated")
        elif "count" in seeds:
            count = _positive_int(path, "seeds.count", seeds["count"])
            first = _positive_int(path, "seeds.first", seeds.get("first", 1), lo=0)
            values = list(range(first, first + count))
        else:
            raise _err(path, "seeds: give values = [...] or count = N")
        if seed_key in varied:
            raise _err(path, f"seeds.key = {seed_key!r}: also varied in a [[grid]]")
        varied.append(seed_key)
        factors.append(("seed", [(None, {seed_key: v}, {}) for v in values]))
    if not factors:
        raise _err(path, "nothing varies: add [seeds], [[grid]] or [[case]]")
    for key in varied:  # a key has one source: a grid or the seeds, never also [set] or a case
        if key in common:
            raise _err(path, f"set.{key}: also varied (by a [[grid]] or [seeds]); remove one")
        for k, c in enumerate(cases):
            if key in flatten({a: b for a, b in c.items() if a not in ("name", "ranks", "threads")}):
                raise _err(path, f"case[{k}].{key}: also varied (by a [[grid]] or [seeds]); remove one")

    local = raw.get("local", {})
    _check_keys(path, "local", local, LOCAL_KEYS)
    cores = _positive_int(path, "local.cores", local["cores"]) if "cores" in local else None
    slurm = raw.get("slurm", {})
    _check_keys(path, "slurm", slurm, SLURM_KEYS)
    slurm = {**SLURM_DEFAULTS, **slurm}
    if slurm["launcher"] not in LAUNCHERS:
        raise _err(path, f"slurm.launcher = {slurm['launcher']!r}: must be one of {', '.join(LAUNCHERS)}")
    for k in ("launcher_args", "options"):
        if not isinstance(slurm[k], list) or not all(isinstance(x, str) for x in slurm[k]):
            raise _err(path, f"slurm.{k} = {slurm[k]!r}: must be a list of strings")
    _positive_int(path, "slurm.signal_lead", slurm["signal_lead"], lo=0)
    _positive_int(path, "slurm.max_running", slurm["max_running"], lo=0)
    if not re.match(r"^(\d+-)?\d+(:\d+){0,2}$", str(slurm["time"])):
        raise _err(path, f"slurm.time = {slurm['time']!r}: must be a SLURM time such as \"24:00:00\" or \"1-12:00:00\"")
    analysis = raw.get("analysis", {})
    if not isinstance(analysis, dict):
        raise _err(path, "[analysis] must be a table")

    camp = Campaign(path=path.resolve(), name=name, base=base, base_text=str(head["base"]), out=out_dir,
                    ranks=ranks, threads=threads, set=common,
                    factors=factors, seed_key=seed_key, varied=varied, has_cases=bool(cases), cores=cores,
                    slurm=slurm, analysis=analysis)
    camp.members = expand(camp, base_doc)
    return camp


def _no_repeats(path, where, values, what):
    """InputError if a value of ``values`` (a grid's list, or a zipped grid's rows) is repeated:
    two members would run one scene (and write one folder)."""
    seen = {}
    for k, v in enumerate(values):
        text = repr(v)
        if text in seen:
            raise _err(path, f"{where}: {what} {k} ({v!r}) repeats {what} {seen[text]}; two members would run the same "
                             "scene: remove one")
        seen[text] = k


def _list_of_tables(path, raw, key):
    v = raw.get(key, [])
    if isinstance(v, dict):
        v = [v]
    if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
        raise _err(path, f"{key}: must be [[{key}]] tables")
    return v


# the most members a campaign may expand to: a SLURM array holds at most MaxArraySize − 1 tasks
# (1 000 by default, some sites 10 000 or more), and every member is checked when it is expanded
MAX_MEMBERS = 10000


def expand(camp, base_doc):
    """The members of a campaign (the cross product of its factors), each checked."""
    n = math.prod(len(levels) for _, levels in camp.factors)
    if n > MAX_MEMBERS:
        raise _err(camp.path, f"expands to {n} members (the product of its cases, grids and seeds): at most "
                              f"{MAX_MEMBERS}; split it into several campaigns")
    short = short_names(camp.varied)
    widths = {}
    for kind, levels in camp.factors:
        if kind in ("grid", "zip", "seed"):
            for key in levels[0][1]:
                widths[key] = _int_width([lv[1][key] for lv in levels])
    members, seen = [], {}
    for combo in itertools.product(*(levels for _, levels in camp.factors)):
        parts, overrides, params, extra = [], dict(camp.set), {}, {}
        for label, sets, more in combo:
            extra.update(more)
            if label is not None:
                parts += label
            for key, v in sets.items():
                if label is None:
                    w = widths.get(key, 0)
                    text = str(v).zfill(w) if w and isinstance(v, int) else value_label(v)
                    parts.append(f"{short[key].replace('.', '-')}-{text}")
                    params[key] = v
                overrides[key] = v
        if "case" in extra:
            params = {"case": extra["case"], **params}
        name = "_".join(parts)
        folded = name.casefold()  # one folder on a case-insensitive file system (macOS, Windows)
        if folded in seen:
            other, params0 = seen[folded]
            same = f"the same name {name!r}" if other == name else f"names {other!r} and {name!r} (one folder where " \
                "case does not count)"
            raise _err(camp.path, f"members {params0} and {params} get {same}; they would write one folder: give "
                                  "the values that differ more digits or other case names")
        seen[folded] = (name, params)
        doc, created = _deepcopy(base_doc), {}
        for key, v in overrides.items():
            try:
                created.update((t, key) for t in set_path(doc, key, v))
            except InputError as exc:
                raise _err(camp.path, f"member {name}: {exc}") from None
        try:
            check_member(doc)
        except InputError as exc:
            hint = "".join(f" ([{t}] is not in the base scene: {k} created it; a typo?)" for t, k in created.items()
                           if str(exc).startswith(t + ".") or str(exc).startswith(t + ":"))
            raise _err(camp.path, f"member {name}: {exc}{hint}") from None
        members.append(Member(name=name, params=params, overrides=overrides, doc=doc,
                              ranks=extra.get("ranks", camp.ranks), threads=extra.get("threads", camp.threads)))
    return members


def jsonable(v):
    """A parameter value for JSON (non-finite floats as text)."""
    if isinstance(v, float) and not math.isfinite(v):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    if isinstance(v, dict):
        return {k: jsonable(x) for k, x in v.items()}
    if hasattr(v, "isoformat"):
        return v.isoformat()
    return v
