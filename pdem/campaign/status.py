"""``pdem campaign status``: every member's state, exit status, attempts, cost and message.

Owns `status_rows` and `format_status`. Reads the campaign directory only (never writes).
"""
from pathlib import Path

from .record import STATES, member_state


def status_rows(out, man):
    """One dict per member: name, state, exit, attempts, wall_s, core_s, message."""
    rows = []
    for e in man["members"]:
        d = Path(out) / e["dir"]
        state, rec, msg = member_state(d) if d.is_dir() else ("pending", None, "not expanded yet")
        ended = [a for a in (rec or {}).get("attempts", []) if a.get("end")]
        rows.append({"name": e["name"], "state": state, "exit": ended[-1]["exit"] if ended else None,
                     "attempts": len((rec or {}).get("attempts", [])), "wall_s": sum(a["wall_s"] for a in ended),
                     "core_s": sum(a["core_s"] for a in ended), "message": msg})
    return rows


def format_status(out, man, rows):
    counts = {s: sum(r["state"] == s for r in rows) for s in STATES}
    head = (f"campaign {man['name']} in {out}: {len(rows)} members: "
            + ", ".join(f"{counts[s]} {s}" for s in STATES))
    w = max([len("member")] + [len(r["name"]) for r in rows])
    lines = [head, f"{'member':<{w}}  {'state':<8} {'exit':>4} {'tries':>5} {'wall [s]':>9} {'core-h':>8}  message"]
    for r in rows:
        ex = "-" if r["exit"] is None else str(r["exit"])
        wall = f"{r['wall_s']:9.1f}" if r["attempts"] else f"{'-':>9}"
        ch = f"{r['core_s'] / 3600:8.4f}" if r["attempts"] else f"{'-':>8}"
        line = f"{r['name']:<{w}}  {r['state']:<8} {ex:>4} {r['attempts']:>5} {wall} {ch}  {r['message']}"
        lines.append(line.rstrip())
    return "\n".join(lines)
