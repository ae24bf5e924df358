"""Helpers shared by the benchmark scripts: timing (best of ``repeat`` runs, wall clock), CPU
time with the worker processes', and the code a result belongs to."""
import hashlib
import json
import resource
import subprocess
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def timed(fn, repeat=1, clock=time.perf_counter):
    """Return (best time in s over ``repeat`` calls, the last result); wall clock unless ``clock``
    says otherwise (``time.process_time``: this process's CPU time, steadier on a busy machine)."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = clock()
        out = fn()
        best = min(best, clock() - t0)
    return best, out


def cpu_s():
    """CPU time (s) of this process and of its children that have ended (pool workers, subprocesses)."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def code_state(*paths):
    """The commit, and whether ``paths`` (default ``src``) had uncommitted changes when the
    benchmark ran, with the SHA-1 of that diff: the numbers belong to that code."""
    paths = list(paths or ("src",))

    def git(*a):
        try:
            return subprocess.run(["git", *a], cwd=ROOT, capture_output=True, text=True, timeout=30).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""
    return {"commit": git("rev-parse", "HEAD"), "paths": paths,
            "dirty": bool(git("status", "--porcelain", "--", *paths)),
            "diff_sha1": hashlib.sha1(git("diff", "--", *paths).encode()).hexdigest()}


def child_json(python, script, args):
    """Run ``script`` (a benchmark in its child mode) with the interpreter ``python`` -- another
    version's, whose installed fdid_fmi it then measures -- and return the last line it printed,
    parsed as JSON, or ``{"error": the last line of its stderr}`` when it failed."""
    p = subprocess.run([python, str(script), *args], capture_output=True, text=True, cwd=ROOT)
    if p.returncode != 0:
        return {"error": (p.stderr.strip().splitlines() or ["?"])[-1][:300]}
    return json.loads(p.stdout.strip().splitlines()[-1])
