"""What the grading child sends back, read as untrusted plain data: call records and the execution report.

Part of the summative grader (seed paper section 4, exercises graded; see
:mod:`coursekit.grading.grader`). The grading child writes JSON lines on a pipe only it holds
(:class:`Collector` reads them, bounded by :data:`MAX_CHANNEL_BYTES`). Every line is checked
against the call the grader sent under its id before it counts (:func:`validate_call`): the
status is one of the registry's, the output is plain data of the check's kind within the call's
size limit, and ``inputs_after`` describes each argument. The execution report says which cells
failed or were skipped (:func:`read_report`); a skipped cell means the score does not stand.
"""

from __future__ import annotations

import json
import os
import re
import stat
import threading
from pathlib import Path

from coursekit.grading.checks import STATUSES

MAX_CHANNEL_BYTES = 64 * 2**20


def read_untrusted(path: Path, limit: int) -> bytes | None:
    """Bytes of a regular file (no symlinks, FIFOs or devices), or None; ValueError when too big."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            return None
        data = f.read(limit + 1)
    if len(data) > limit:
        raise ValueError(f"{path.name} exceeds {limit} bytes")
    return data


def reject_constant(name):
    """``json.loads``'s ``parse_constant``: NaN and infinities are not plain data."""
    raise ValueError(f"non-finite number {name}")


def _plain_list(v, max_len, depth):
    """Is v a list of ints/finite floats (depth 1) or of such lists (depth 2), within max_len?"""
    if type(v) is not list or len(v) > max_len:
        return False
    if depth == 1:
        return all(type(x) in (int, float) for x in v)
    return all(_plain_list(x, max_len, depth - 1) for x in v)


def _valid_output(out, check, max_len) -> bool:
    """Is ``out`` one call's converted result of the kind ``check.output`` (plain data within ``max_len``)?"""
    if check.output == "json":
        return type(out) is str and len(out) <= max_len
    if check.output == "json_pair":
        return type(out) is list and len(out) == 2 and all(type(t) is str and len(t) <= max_len for t in out)
    if check.output == "array_pair":
        return _plain_list(out, max_len, 2) and len(out) == 2
    if not _plain_list(out, max_len, 1):
        return False
    return check.output != "indices" or all(type(x) is int for x in out)


def _valid_after(a, encoded, max_len) -> bool:
    if a is None:
        return True
    if type(a) is not dict:
        return False
    if set(a) == {"ndarray", "dtype"}:
        return type(a["dtype"]) is str and _plain_list(a["ndarray"], max_len, 1)
    if set(a) != {"json"} or type(a["json"]) is not str or len(a["json"]) > max_len:
        return False
    try:  # the supervisor compares it with what it sent: it must parse there
        json.loads(a["json"], parse_constant=reject_constant)
    except (ValueError, RecursionError):
        return False
    return True


def validate_call(rec, check, call) -> dict | None:
    """A call record from the grading child as a clean dict, or None when it is malformed in any way.

    ``call`` is the call the grader sent under that record's id (None when the id is unknown).
    """
    if type(rec) is not dict or rec.get("check") != check.name or call is None or rec.get("id") != call["id"]:
        return None
    status = rec.get("status")
    if status not in STATUSES:
        return None
    clean = {"id": call["id"], "status": status}
    if "error" in rec:
        if type(rec["error"]) is not str:
            return None
        clean["error"] = rec["error"][:600]
    if status == "ok":
        if "output" not in rec or not _valid_output(rec["output"], check, call["max_len"]):
            return None
        after = rec.get("inputs_after")
        if type(after) is not list or len(after) != len(call["args"]) or \
                not all(_valid_after(a, e, call["max_len"]) for a, e in zip(after, call["args"])):
            return None
        clean.update(output=rec["output"], inputs_after=after)
    return clean


def read_results(data: bytes, checks: list, plan: dict) -> tuple[dict, dict | None, int]:
    """Parse what the grading child sent on its pipe.

    Args:
        data: the JSON lines received.
        checks: the notebook's checks.
        plan: ``{check name: {call id: (case id, call index, call)}}``, what the grader sent.
    Returns:
        a tuple: ``{check name: {(case id, index): clean call record}}``, the execution report or
        None, and the number of rejected lines. The first record of a call counts.
    """
    by_name = {c.name: c for c in checks}
    results: dict = {c.name: {} for c in checks}
    report, rejected = None, 0
    for line in data.splitlines():
        try:
            rec = json.loads(line, parse_constant=reject_constant)
        except (ValueError, RecursionError):
            rejected += 1
            continue
        if type(rec) is dict and set(rec) == {"report"}:
            report = rec["report"]
            continue
        check = by_name.get(rec.get("check")) if type(rec) is dict and type(rec.get("check")) is str else None
        sent = plan.get(check.name, {}).get(rec.get("id")) if check and type(rec.get("id")) is str else None
        try:
            clean = validate_call(rec, check, sent[2]) if sent else None
        except (TypeError, ValueError):
            clean = None
        if clean is None:
            rejected += 1
        else:
            results[check.name].setdefault(sent[:2], clean)
    return results, report, rejected


#: Cells named per status, and statuses listed, in a notebook's notes (the rest are counted).
MAX_CELLS_SHOWN = 20
#: A cell's status when it stopped at a function the sandbox withholds (:func:`.executor._error_name`).
_WITHHELD = re.compile(r"error: uses coursekit's own (\S+), withheld while grading")


def read_report(rep) -> tuple[list, list]:
    """``(notes, problems)`` from the execution report: which cells failed, and which were skipped.

    A *problem* means part of the notebook never ran (a cell skipped for time, memory or a crash,
    or no report at all), so its score cannot stand; an error raised by a cell is only a note.
    """
    if type(rep) is not dict or rep.get("format") != "coursekit.execution/1":
        return [], ["no execution report (the notebook run was stopped)"]
    notes, problems = [], []
    if type(rep.get("error")) is str:
        notes.append(rep["error"][:400])
    elif rep.get("harvested") is not True and type(rep.get("harvest_problem")) is not str:
        problems.append("the graded functions were never called (the kernel did not get that far)")
    if type(rep.get("harvest_problem")) is str:
        problems.append(rep["harvest_problem"][:300])
    cells = rep.get("cells") if type(rep.get("cells")) is list else []
    failed: dict[str, list[int]] = {}  # status -> cells, in the order first seen: one line per distinct status
    for c in cells:  # every cell: one skipped after the 200th still means part of the notebook never ran
        if type(c) is dict and type(c.get("status")) is str and type(c.get("index")) is int and c["status"] != "ok":
            failed.setdefault(c["status"][:200], []).append(c["index"] + 1)
    lines: dict[bool, list] = {True: [], False: []}
    held = {}  # cells stopped by a withheld function of the library: one calm line for all of them
    for status in list(failed):
        m = _WITHHELD.match(status)
        if m:
            held.setdefault(m[1], []).extend(failed.pop(status))
    if held:
        where = sorted({i for cells in held.values() for i in cells})
        shown = ", ".join(map(str, where[:MAX_CELLS_SHOWN])) + \
            (f" and {len(where) - MAX_CELLS_SHOWN} more" if len(where) > MAX_CELLS_SHOWN else "")
        names = list(held)
        named = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
        lines[False].append(f"cell{'s' * (len(where) > 1)} {shown} call{'s' * (len(where) == 1)} coursekit's own {named}, "
                            f"which {'is' if len(names) == 1 else 'are'} switched off while your functions are graded: "
                            f"{'those cells stop' if len(where) > 1 else 'that cell stops'} there, and that does not "
                            "change your score")
    for status, where in failed.items():
        shown = ", ".join(map(str, where[:MAX_CELLS_SHOWN])) + \
            (f" and {len(where) - MAX_CELLS_SHOWN} more" if len(where) > MAX_CELLS_SHOWN else "")
        lines[status.startswith(("skipped", "not run"))].append(f"cell{'s' * (len(where) > 1)} {shown}: {status}")
    for out, more in ((notes, lines[False]), (problems, lines[True])):
        out += more[:MAX_CELLS_SHOWN]
        if len(more) > MAX_CELLS_SHOWN:
            out.append(f"and {len(more) - MAX_CELLS_SHOWN} more kinds")
    return notes, problems



class Collector(threading.Thread):
    """Read the grading child's pipe into memory, up to MAX_CHANNEL_BYTES (the rest is drained and dropped)."""

    def __init__(self, fd):
        super().__init__(daemon=True)
        self.fd, self.data, self.overflow = fd, bytearray(), False

    def run(self):
        with os.fdopen(self.fd, "rb", buffering=0) as f:
            while True:
                chunk = f.read(1 << 16)
                if not chunk:
                    return
                if len(self.data) + len(chunk) > MAX_CHANNEL_BYTES:
                    self.overflow = True
                else:
                    self.data += chunk

