"""Build and drive tests/c_host/host.c, a C FMI 2.0 master with no Python in the loop."""
from __future__ import annotations

import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
HOST_C = ROOT / "tests" / "c_host" / "host.c"
INCLUDE = ROOT / "src" / "fdid_fmi" / "fmu_templates" / "include"


def build_host(out_dir, cc="gcc", exe="host"):
    """Compile the host with ``cc`` (gcc, or x86_64-w64-mingw32-gcc for a Windows .exe)."""
    out = Path(out_dir) / exe
    cmd = [cc, "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", "-I", str(INCLUDE), str(HOST_C),
           "-o", str(out)]
    if "mingw" not in cc:
        cmd.append("-ldl")
    else:
        cmd.append("-static")
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return out


def unpack(fmu, out_dir):
    """Extract an FMU; returns (directory, model description)."""
    from fmpy import read_model_description
    d = Path(out_dir)
    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(d)
    return d, read_model_description(str(fmu))


def host_args(md, lib, mode, inputs, outputs, n, in_file, out_file, Ts, comm=1, ninst=1, params=None):
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    args = [mode, str(lib), md.guid, repr(Ts), str(n), str(comm), str(ninst), str(in_file), str(out_file),
            str(len(inputs)), str(len(outputs))]
    args += [str(vrs[k]) for k in inputs] + [str(vrs[k]) for k in outputs]
    params = params or {}
    args += [str(len(params))]
    for k, v in params.items():
        args += [str(vrs[k]), repr(float(v))]
    return args


def run_host(host, fmu, inputs, outputs, Ts, mode="run", comm=1, ninst=1, params=None, prefix=(),
             lib_platform="linux64", timeout=600):
    """Run the C host on an FMU.

    Parameters
    ----------
    inputs : dict name -> array (n,)
    outputs : list of names
    prefix : command prefix (e.g. ``["valgrind", ...]`` or ``["wine"]``)

    Returns
    -------
    (CompletedProcess, outputs array (ninst, n // comm, len(outputs)) or None)
    """
    tmp = Path(tempfile.mkdtemp(prefix="fdid_host_"))
    try:
        d, md = unpack(fmu, tmp / "fmu")
        ident = md.coSimulation.modelIdentifier
        lib = d / "binaries" / lib_platform / (ident + (".dll" if lib_platform == "win64" else ".so"))
        names = list(inputs)
        n = len(next(iter(inputs.values())))
        U = np.column_stack([np.asarray(inputs[k], float) for k in names])
        (tmp / "in.bin").write_bytes(np.ascontiguousarray(U).tobytes())
        args = host_args(md, lib, mode, names, outputs, n, tmp / "in.bin", tmp / "out.bin", Ts, comm,
                         ninst, params)
        proc = subprocess.run([*prefix, str(host), *args], capture_output=True, text=True, timeout=timeout)
        Y = None
        if mode == "run" and proc.returncode == 0:
            Y = np.frombuffer((tmp / "out.bin").read_bytes(), dtype=float).reshape(ninst, n // comm, len(outputs))
        return proc, Y
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
