"""codac 2 side of the oracle test and the benchmark. codac runs ONLY in a subprocess.

``import codac`` switches the whole process to upward rounding, so codac is never imported by
tileviz or by the pytest process: ``tests/test_codac_oracle.py`` and ``bench/bench_localizer.py``
call :func:`run`, which starts this file as a script with ``sys.executable`` and talks JSON over
stdin/stdout (importing this module imports no codac).
Under upward rounding CPython parses about one decimal float literal in five one ulp off (its
fast path divides in floats), so the worker reads and parses its whole input *before* importing
codac, and writes every bound it returns as ``float.hex`` (read back with :func:`decode`).

The constraint, for one rotation branch m of an observation (docs/method.md, "Contraction"),
over the 6-box (x, y, theta, y1, y2, y3) where [y1], [y2], [y3] are the observation +- its bounds:

    c_x = x + rho cos(theta + phi),   c_y = y + rho sin(theta + phi)   (the camera lever arm)
    (u1, u2) = R(m pi/2) (y1, y2)    m=0: (y1, y2), 1: (-y2, y1), 2: (-y1, -y2), 3: (y2, -y1)
    sin(pi (c_x - u1) / L) = 0,  sin(pi (c_y - u2) / L) = 0,  sin((theta - y3 - m pi/2) / 2) = 0

The last one says theta - y3 - m pi/2 in 2 pi Z (the heading branch, modulo 2 pi: unlike the
original's sin(x3 - y3) = 0 it does not identify a half turn with no turn). The lever arm is
written rho cos(theta + phi) rather than f cos(theta) - l sin(theta) so that theta occurs once
and the forward-backward projection is exact.

Input (JSON on stdin)::

    {"task": "contract", "jobs": [{"L", "rho", "phi", "m": 0..3 | "union",
                                   "box": [[lo, hi] x 6], "cell": null | [kx, ky, j]}, ...]}
    {"task": "bench", "L", "rho", "phi", "boxes": [[[lo, hi] x 6], ...], "repeats": int}

``echo``: {"task": "echo", "values": [float, ...]} returns {"values": [hex, ...]}, the floats as
parsed, to check that the input reaches codac's process exactly.

``contract``: CtcInverse of the three sin constraints (codac's default, with the centered form),
iterated to a fixpoint (until no bound moves). With ``cell``, the contractor is intersected with a
second CtcInverse that pins the lattice cell: c_x - u1 = kx L, c_y - u2 = ky L,
theta - y3 - m pi/2 = 2 pi j. With ``"m": "union"``: CtcUnion of the four branch contractors,
each wrapped in CtcFixpoint(ratio 0). Output: {"results": [[[lo, hi] x 6] | null, ...]}, every
bound as ``float.hex``.

``bench``: the time of one contraction of each box by the union over m = 0..3 (CtcUnion) of the
branch contractors, single pass and to a fixpoint (CtcFixpoint), with and without the centered
form. Output: {"us_per_box": {name: microseconds}, "empty": {name: count}}.
"""

from __future__ import annotations

import json
import math
import sys
import time
from typing import Any

cd: Any = None
"""The codac module, imported by :func:`main` once the input is parsed (see the docstring)."""


def run(spec: dict, timeout: float = 900.0) -> dict:
    """The worker's answer to ``spec`` (one of the inputs above), from a fresh interpreter;
    ``results`` decoded (:func:`decode`). RuntimeError with the worker's stderr if it fails."""
    import subprocess

    r = subprocess.run([sys.executable, __file__], input=json.dumps(spec), capture_output=True,
                       text=True, timeout=timeout)
    if r.returncode != 0:
        raise RuntimeError(f"codac worker failed: {r.stderr.strip()}")
    out = json.loads(r.stdout)
    if "results" in out:
        out["results"] = decode(out["results"])
    return out


def decode(results: list) -> list:
    """``results`` of a ``contract`` answer with every ``float.hex`` bound read back as a float
    (for the caller, in its own round-to-nearest process)."""
    return [None if r is None else [[float.fromhex(lo), float.fromhex(hi)] for lo, hi in r]
            for r in results]


def _branch_function(L: float, rho: float, phi: float, m: int) -> tuple[Any, Any]:
    """(sin-constraint function, cell function) of branch m over (x, y, theta, y1, y2, y3)."""
    v = cd.VectorVar(6)
    cx = v[0] + rho * cd.cos(v[2] + phi)
    cy = v[1] + rho * cd.sin(v[2] + phi)
    u1, u2 = [(v[3], v[4]), (-v[4], v[3]), (-v[3], -v[4]), (v[4], -v[3])][m]
    k = math.pi / L
    f_sin = cd.AnalyticFunction(
        [v],
        cd.vec(
            cd.sin(k * (cx - u1)),
            cd.sin(k * (cy - u2)),
            cd.sin(0.5 * (v[2] - v[5] - m * 0.5 * math.pi)),
        ),
    )
    f_cell = cd.AnalyticFunction([v], cd.vec(cx - u1, cy - u2, v[2] - v[5]))
    return f_sin, f_cell


def _box(b: list[list[float]]) -> Any:
    return cd.IntervalVector([[lo, hi] for lo, hi in b])


def _out(b: Any) -> list[list[float]] | None:
    if b.is_empty():
        return None
    return [[b[i].lb().hex(), b[i].ub().hex()] for i in range(6)]


def _fixpoint(ctc: Any, b: Any, limit: int = 200) -> Any:
    prev = None
    for _ in range(limit):
        b = ctc.contract(b)
        if b.is_empty():
            return b
        cur = [(b[i].lb(), b[i].ub()) for i in range(6)]  # compared, never parsed: exact
        if cur == prev:
            break
        prev = cur
    return b


def contract(jobs: list[dict]) -> dict:
    funcs: dict[tuple, tuple[Any, Any]] = {}
    ctcs: dict[tuple, Any] = {}
    results = []
    unions: dict[tuple, Any] = {}
    for job in jobs:
        if job["m"] == "union":
            ukey = (job["L"], job["rho"], job["phi"])
            if ukey not in unions:
                zero = cd.IntervalVector([[0.0]] * 3)
                unions[ukey] = cd.CtcUnion([
                    cd.CtcFixpoint(cd.CtcInverse(_branch_function(*ukey, m)[0], zero), 0.0)
                    for m in range(4)
                ])
            results.append(_out(unions[ukey].contract(_box(job["box"]))))
            continue
        key = (job["L"], job["rho"], job["phi"], job["m"])
        if key not in funcs:
            funcs[key] = _branch_function(*key)
            ctcs[key] = cd.CtcInverse(funcs[key][0], cd.IntervalVector([[0.0]] * 3))
        ctc = ctcs[key]
        if job.get("cell") is not None:
            kx, ky, j = job["cell"]
            L, m = job["L"], job["m"]
            target = cd.IntervalVector(
                [[kx * L], [ky * L], [m * 0.5 * math.pi + 2.0 * math.pi * j]]
            )
            ctc = cd.CtcInter(ctc, cd.CtcInverse(funcs[key][1], target))
        results.append(_out(_fixpoint(ctc, _box(job["box"]))))
    return {"results": results}


def bench(spec: dict) -> dict:
    L, rho, phi = spec["L"], spec["rho"], spec["phi"]
    boxes = [_box(b) for b in spec["boxes"]]
    repeats = int(spec.get("repeats", 1))
    zero = cd.IntervalVector([[0.0]] * 3)
    variants = {}
    for centered in (True, False):
        branch = [
            cd.CtcInverse(_branch_function(L, rho, phi, m)[0], zero, centered) for m in range(4)
        ]
        tag = "centered" if centered else "plain"
        variants[f"union4_{tag}_1pass"] = cd.CtcUnion(branch)
        variants[f"union4_{tag}_fixpoint"] = cd.CtcUnion([cd.CtcFixpoint(c, 0.0) for c in branch])
    us: dict[str, float] = {}
    empty: dict[str, int] = {}
    for name, ctc in variants.items():
        best = math.inf
        n_empty = 0
        for _ in range(repeats):
            copies = [cd.IntervalVector(b) for b in boxes]
            t0 = time.perf_counter()
            for b in copies:
                ctc.contract(b)
            best = min(best, time.perf_counter() - t0)
        for b in boxes:
            if ctc.contract(cd.IntervalVector(b)).is_empty():
                n_empty += 1
        us[name] = best / len(boxes) * 1e6
        empty[name] = n_empty
    return {"us_per_box": us, "empty": empty}


def main() -> int:
    global cd
    spec = json.loads(sys.stdin.read())  # parsed in round-to-nearest, before codac is imported
    import codac

    cd = codac
    task = spec.get("task")
    if task == "echo":
        out: dict = {"values": [float(v).hex() for v in spec["values"]]}
    elif task == "contract":
        out = contract(spec["jobs"])
    elif task == "bench":
        out = bench(spec)
    else:
        sys.stderr.write(f"codac_oracle_worker: unknown task {task!r}\n")
        return 2
    json.dump(out, sys.stdout)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
