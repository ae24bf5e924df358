"""The FMU outside fmpy: a C host (dlopen), valgrind, the ecos co-simulation engine, wine."""
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import fmu_support as fs
from fdid_fmi.fmu import export_fmu
from fdid_fmi.fmu.build import compiler_available
from fdid_fmi.fmu.validate import run_fmu
from fmu_support.host import build_host, run_host

N = 2000


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.skip("gcc is not installed")
    d = tmp_path_factory.mktemp("hosts")
    m = fs.coupled_model()
    plats = ("linux64", "win64") if compiler_available("win64") else ("linux64",)
    fmu = export_fmu(m, d / "coupled.fmu", platforms=plats)
    rng = np.random.default_rng(21)
    cmds = {a: fs.smooth_moves(N, rng, start=4.0 + i) for i, a in enumerate(m.axes)}
    return {"dir": d, "model": m, "fmu": fmu, "host": build_host(d), "cmds": cmds,
            "outs": ["x_x", "x_v", "y_x", "y_v"]}


def test_c_host_instances_are_independent_and_equal_fmpy(setup):
    """Three instances stepped interleaved in one process, each with its own input."""
    s = setup
    ins = {f"{a}_x_cmd": c for a, c in s["cmds"].items()}
    proc, Y = run_host(s["host"], s["fmu"], ins, s["outs"], s["model"].Ts, ninst=3)
    assert proc.returncode == 0, proc.stderr
    for i in range(3):
        ref = run_fmu(s["fmu"], {a: c * (1 + 0.25 * i) for a, c in s["cmds"].items()}, s["model"].Ts,
                      outputs=s["outs"])
        for j, name in enumerate(s["outs"]):
            assert np.array_equal(Y[i, :, j], ref[name]), (i, name)
    assert not np.allclose(Y[0, :, 0], Y[1, :, 0])


def test_c_host_misuse_and_state_checks(setup):
    s = setup
    ins = {f"{a}_x_cmd": c for a, c in s["cmds"].items()}
    proc, _ = run_host(s["host"], s["fmu"], ins, s["outs"], s["model"].Ts, mode="errors")
    assert proc.returncode == 0, proc.stderr
    assert "errors ok" in proc.stdout


@pytest.mark.parametrize("mode", ["run", "errors"])
def test_valgrind_100_instances_no_leak_no_invalid_access(setup, mode):
    if shutil.which("valgrind") is None:
        pytest.skip("valgrind is not installed (apt-get install valgrind)")
    s = setup
    ins = {f"{a}_x_cmd": c[:100] for a, c in s["cmds"].items()}
    vg = ["valgrind", "--error-exitcode=1", "--leak-check=full", "--errors-for-leak-kinds=definite,indirect",
          "-q"]
    proc, Y = run_host(s["host"], s["fmu"], ins, s["outs"], s["model"].Ts, mode=mode,
                       ninst=100 if mode == "run" else 1, prefix=vg)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Invalid" not in proc.stderr and "definitely lost" not in proc.stderr
    if mode == "run":
        assert Y.shape == (100, 100, len(s["outs"])) and np.isfinite(Y).all()


def test_ecos_engine_equals_fmpy(setup):
    """The ecos co-simulation engine (ecospy, C++ libecos) gives fmpy's numbers.

    ecos records outputs after each step (input k held over [t_k, t_k+1]); the fmpy run reads
    at the same points (``read="after"``).
    """
    try:
        from ecospy import EcosSimulation, EcosSimulationStructure
    except (ImportError, OSError) as exc:  # OSError: libtbb12 missing
        pytest.skip(f"ecospy is not usable ({exc}); pip install ecospy and apt-get install libtbb12")
    s = setup
    m, n = s["model"], 1000
    ss = EcosSimulationStructure()
    ss.add_model("drive", str(s["fmu"]))
    sim = EcosSimulation(structure=ss, step_size=m.Ts)
    try:
        for a, c in s["cmds"].items():
            sim.set_real(f"drive::{a}_x_cmd", c[0])
        sim.init()
        got = np.empty((n, len(s["outs"])))
        for k in range(n):
            for a, c in s["cmds"].items():
                sim.set_real(f"drive::{a}_x_cmd", c[k])
            sim.step()
            got[k] = [sim.get_real(f"drive::{o}") for o in s["outs"]]
        assert sim.get_time() == pytest.approx(n * m.Ts)
    finally:
        sim.terminate()
        sim.free()
    ref = run_fmu(s["fmu"], {a: c[:n] for a, c in s["cmds"].items()}, m.Ts, outputs=s["outs"], read="after")
    for j, name in enumerate(s["outs"]):
        assert np.array_equal(got[:, j], ref[name]), name


def _wine():
    for w in ("wine64", "wine"):
        if shutil.which(w):
            return shutil.which(w)
    if Path("/usr/lib/wine/wine64").exists():
        return "/usr/lib/wine/wine64"
    return None


def test_win64_dll_runs_under_wine(setup, tmp_path):
    if not compiler_available("win64"):
        pytest.skip("x86_64-w64-mingw32-gcc is not installed (apt-get install gcc-mingw-w64-x86-64)")
    wine = _wine()
    if wine is None:
        pytest.skip("wine is not installed, so the win64 DLL is built but not run "
                    "(apt-get install wine64 to run it)")
    s = setup
    exe = build_host(tmp_path, cc="x86_64-w64-mingw32-gcc", exe="host.exe")
    env_prefix = ["env", "WINEDEBUG=-all", f"WINEPREFIX={tmp_path / 'wineprefix'}", wine]
    ins = {f"{a}_x_cmd": c[:500] for a, c in s["cmds"].items()}
    proc, Y = run_host(exe, s["fmu"], ins, s["outs"], s["model"].Ts, ninst=2, prefix=env_prefix,
                       lib_platform="win64", timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    ref = run_fmu(s["fmu"], {a: c[:500] for a, c in s["cmds"].items()}, s["model"].Ts, outputs=s["outs"])
    for j, name in enumerate(s["outs"]):
        assert np.abs(Y[0, :, j] - ref[name]).max() <= 1e-9, name
    proc, _ = run_host(exe, s["fmu"], ins, s["outs"], s["model"].Ts, mode="errors", prefix=env_prefix,
                       lib_platform="win64", timeout=300)
    assert proc.returncode == 0 and "errors ok" in proc.stdout, proc.stderr[-2000:]


def test_ecos_cli_equals_fmpy(tmp_path):
    """The ``ecos`` command-line co-simulation engine (shipped in ecospy) runs the FMU with a
    scenario of command steps; its CSV (6 decimals) equals fmpy's run of the same schedule."""
    try:
        import ecospy
    except (ImportError, OSError) as exc:
        pytest.skip(f"ecospy is not usable ({exc})")
    src = Path(ecospy.__file__).parent / "binaries" / "ecos"
    if not src.is_file():
        pytest.skip("ecospy ships no ecos executable for this platform")
    exe = tmp_path / "ecos"
    shutil.copy(src, exe)
    exe.chmod(0o755)                      # the wheel installs it without the executable bit
    probe = subprocess.run([str(exe), "--version"], capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"the ecos executable does not run here ({probe.stderr.strip()[:200]}; "
                    f"apt-get install libtbb12)")
    m = fs.siso_model()
    fmu = export_fmu(m, tmp_path / "drive.fmu")
    steps = [(0.05, 0.5), (0.1, -0.25), (0.16, 0.75)]
    actions = "\n".join(
        f'  <ecos:action t="{t}"><ecos:variable id="instance::x_x_cmd"><ecos:real value="{v}"/>'
        f"</ecos:variable></ecos:action>" for t, v in steps)
    (tmp_path / "scenario.xml").write_text(
        '<?xml version="1.0" encoding="utf-8"?>\n<ecos:Scenario '
        'xmlns:ecos="http://github.com/Ecos-platform/libecos/resources/schema/ScenarioConfig">\n'
        f"{actions}\n</ecos:Scenario>\n")
    n = 250
    proc = subprocess.run([str(exe), "simulate", "--path", str(fmu), "--stepSize", repr(m.Ts),
                           "--stopTime", repr((n + 1) * m.Ts), "--scenarioConfig", str(tmp_path / "scenario.xml")],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    csv = tmp_path / "drive.csv"
    header = [h.strip() for h in csv.read_text().splitlines()[0].split(",")]
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    col = {h.split("::")[-1].split("[")[0]: i for i, h in enumerate(header)}
    cmd = np.zeros(n)
    for t, v in steps:
        cmd[int(round(t / m.Ts)):] = v
    ref = run_fmu(fmu, {"x": cmd}, m.Ts, outputs=["x_x", "x_v"], read="after")
    rows = data[1:n + 1]                  # row k+1 = after step k
    assert np.allclose(rows[:, 1], (np.arange(n) + 1) * m.Ts)
    for name in ("x_x", "x_v"):
        assert np.abs(rows[:, col[name]] - ref[name]).max() <= 1e-6, name
    assert np.abs(ref["x_x"]).max() > 0.5       # the steps moved the axis
