"""Writes the fitted models that tests only run, export or check (tests/data/*_model.json), each
with the identification call (fixed seed and search budget) that its test file once made itself:

- ``twin_no_feedforward_model.json``, ``twin_feedforward_model.json``, ``twin_play_law_model.json``,
  ``twin_emps_model.json``: the identified twins of ``test_fmu_masters.py`` (virtual drive without
  and with feed-forward, plant2's Stribeck axis with the play law and its breakaway term, EMPS
  from ``../shared/data/emps``);
- ``flexible_tool_model.json``, ``coupled_xy_model.json``: the flexible-mode and the coupled
  two-axis models of ``test_fmu_identified.py``;
- ``coupling_two_axis_model.json``: ``fdid identify`` (default method and structure choice,
  ``--maxiter 5``) on the CSV of the ``coupling`` scenario's 6-move training trace, the combined
  per-axis model of ``test_diagnose_combined.py``;
- ``plant2_clean_rigid_siso_model.json``: the pole search (rigid structure, default search) on
  plant2's ``clean_rigid`` training trace, the twin of ``test_rest_plant2.py``.

Deterministic (seed 0, BLAS on one thread). Run from the project root, all or some by name:
``.venv/bin/python tests/data/make_fitted_models.py [NAME ...]`` (a few CPU-minutes in all).
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import sys  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))          # tests/: plant2

from fdid_fmi.identify import Bounds, identify_mimo, identify_siso, mimo_structure  # noqa: E402
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine  # noqa: E402
from fdid_fmi.virtual import trajectories as tj  # noqa: E402

EMPS = HERE.parents[2] / "shared" / "data" / "emps"


def virtual_train(cfg, ax="x"):
    """Eight moves of one axis of ``cfg`` (seed 1): the twins' training trace."""
    one = MachineConfig(axes=[cfg.axis(ax)], Ts=cfg.Ts)
    return simulate_machine(one, tj.linear_moves(n_moves=8, axes=(ax,), Ts=cfg.Ts, seed=1), seed=1)


def twin_no_feedforward():
    return identify_siso(virtual_train(presets.deckel_maho_like()), "x", seed=0, maxiter=30, same_sample="hold")


def twin_feedforward():
    return identify_mimo(virtual_train(presets.with_feedforward()),
                         mimo_structure(("x",), ("error",), 2, 1, same_sample="cubic"), seed=0, maxiter=30)


def twin_play_law():
    """Presliding friction (the play's state runs in the FMU) and its breakaway, on the play's
    terms (what diagnosis adds on this axis: ``augment.add_stribeck``)."""
    from fdid_fmi.identify.structure import InputSpec
    from plant2 import scenarios as p2
    train, _, _ = p2.scenario("stribeck")
    st = mimo_structure(("x",), ("error",), 1, 2, friction=False, play_mm=0.002, same_sample="quadratic")
    brk = InputSpec("feature", "x", params={"function": "play_stribeck", "width_mm": 0.002, "v_s": 3.0,
                                            "source": "position"})
    st.inputs.append(brk)
    st.mask.update({(o, brk.name): t for (o, i), t in list(st.mask.items()) if i == "x_play"})
    return identify_mimo(train, st, seed=0, maxiter=30)


def twin_emps():
    from fdid_fmi.io import read_trace
    tr = read_trace(EMPS / "DATA_EMPS.mat")
    return identify_siso(tr, "x", integral_action=False, seed=0, maxiter=30, same_sample="hold")


def flexible_tool():
    """The flexible Y axis, fitted on velocity and tool position (the second pair searched
    between 20 and 40 Hz, thesis Table 7-3)."""
    cfg = presets.flexible_y()
    nyq = 0.5 / cfg.Ts
    train = virtual_train(cfg, "y")
    return identify_mimo(train, mimo_structure(("y",), ("velocity", "tool_position"), 1, 2, same_sample="hold"),
                         bounds=Bounds([(0.02, nyq)], [(0.02, nyq), (20.0, 40.0)], [(0.01, 4.0), (0.001, 0.5)]),
                         seed=0, maxiter=40)


def coupled_xy():
    """One 6th-order denominator for X and Y, its bounds from two decoupled 3rd-order models."""
    cfg = presets.coupled_xy()
    train = [simulate_machine(cfg, tj.spiral(Ts=cfg.Ts), seed=5)]
    dec = [identify_mimo(train, mimo_structure((ax,), ("error",), 1, 1, same_sample="hold"), seed=0, maxiter=20)
           for ax in "xy"]
    real = [d.identification["real_hz"][0] for d in dec]
    cplx = [d.identification["complex_hz_zeta"][0] for d in dec]
    bounds = Bounds([(r / 1.5, r * 1.5) for r in real], [(w / 1.5, w * 1.5) for w, _ in cplx],
                    [(z / 2, min(2 * z, 4.0)) for _, z in cplx])
    vt = {ax: d.identification["v_tilde_regressor_mm_s"][ax] for ax, d in zip("xy", dec)}
    return identify_mimo(train, mimo_structure(("x", "y"), ("error",), 2, 2, coupled=True, same_sample="hold"),
                         bounds=bounds, v_tilde=vt, seed=0, maxiter=10)


def coupling_two_axis():
    import tempfile
    from fdid_fmi.cli import main
    from fdid_fmi.diagnose.scenarios import scenario
    from fdid_fmi.model import load_model
    from cli_support import write_positions_csv
    tr, _ = scenario("coupling", n_moves=6)
    with tempfile.TemporaryDirectory() as d:
        write_positions_csv(tr, Path(d) / "train.csv")
        assert main(["identify", str(Path(d) / "train.csv"), "-o", str(Path(d) / "model.json"), "--maxiter", "5"]) == 0
        return load_model(Path(d) / "model.json")


def plant2_clean_rigid_siso():
    from plant2 import scenarios as p2
    train, _, truth = p2.scenario("clean_rigid")
    return identify_siso(train[0], truth["axis"], seed=0)


MODELS = {"twin_no_feedforward": twin_no_feedforward, "twin_feedforward": twin_feedforward,
          "twin_play_law": twin_play_law, "twin_emps": twin_emps, "flexible_tool": flexible_tool,
          "coupled_xy": coupled_xy, "coupling_two_axis": coupling_two_axis, "plant2_clean_rigid_siso": plant2_clean_rigid_siso}


if __name__ == "__main__":
    for name in sys.argv[1:] or MODELS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = MODELS[name]()
        out = HERE / f"{name}_model.json"
        model.save(out)
        print(out, model.axes, model.Ts, len(model.poles), "poles")
