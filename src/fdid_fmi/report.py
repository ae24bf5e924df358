"""Self-contained HTML reports: text, tables and matplotlib figures (PNG embedded as base64),
plus a JSON of every figure's data, so a reader can replot or check any number.

    rep = Report("Diagnosis of model.json")
    rep.add_text("What was found ...", heading="Summary")
    rep.add_table("errors", rows, columns=["trace", "axis", "RMS [µm]"], caption="...")
    fig, ax = plt.subplots(); ax.plot(t, r)
    rep.add_figure("residual", fig, data={"t_s": t, "residual_um": r}, caption="...")
    rep.write("report.html")              # one file, no external resources
    rep.write_json("report.json")         # every table and figure's data

A table's columns may be keys (``contour_max_um``): the HTML shows each with its label and
unit from :mod:`fdid_fmi.labels` ("contour error MAX [µm]"), the JSON keeps the keys in
``columns`` and the labels in ``labels``. Every table sits in a container that scrolls
sideways when the table is wider than the page.

The HTML embeds the same JSON in a ``<script type="application/json" id="report-data">``
element. Arrays are written as lists; long series can be decimated by the caller (the figure's
data should be what is plotted). Figures are closed after they are rendered.
"""
from __future__ import annotations

import base64
import html
import io
import json
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from .labels import LABELS, label, metric_label
from .model import jsonable
from .outputs import atomic_write

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;
margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #444;padding-bottom:.2em}
h2{font-size:1.25em;margin-top:1.8em;border-bottom:1px solid #bbb}
h3{font-size:1.05em}
.table-wrap{max-width:100%;overflow-x:auto;margin:.6em 0 1.2em 0}
table{border-collapse:collapse;font-size:.92em}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}
figure{margin:1em 0}figcaption{font-size:.9em;color:#555}
img{max-width:100%}
.meta{color:#666;font-size:.85em}
pre{background:#f6f6f6;padding:.6em;overflow-x:auto;font-size:.85em}
"""


_jsonable = jsonable  # one definition, in model.py
_FMT = "{:.3g}"       # numbers in tables: 3 significant digits (whole numbers from 1000 to 1e6)


class Report:
    """A report being built; see module docstring.

    Parameters
    ----------
    title : str
    meta : dict, optional   free facts shown under the title and saved in the JSON
    """

    def __init__(self, title, meta=None):
        self.title = str(title)
        self.meta = dict(meta or {})
        self.meta.setdefault("created_utc", datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S"))
        self._blocks = []          # (kind, payload)
        self.figures = {}          # name -> data
        self.tables = {}           # name -> {"columns", "rows"}
        self.extra = {}            # name -> any JSON-able data

    # ----------------------------------------------------------------- content
    def add_heading(self, text, level=2):
        self._blocks.append(("heading", (int(level), str(text))))

    def add_text(self, text, heading=None):
        """A paragraph (plain text; blank lines separate paragraphs)."""
        if heading:
            self.add_heading(heading)
        self._blocks.append(("text", str(text)))

    def add_code(self, text):
        self._blocks.append(("code", str(text)))

    def add_table(self, name, rows, columns=None, caption="", fmt=None):
        """A table. ``rows``: list of dicts (``columns`` picks and orders the keys) or of lists.
        Columns are shown with their labels (:func:`fdid_fmi.labels.label`)."""
        fmt = fmt or _FMT
        name = _unique(name, self.tables)      # a second 'errors' replaced the first in the JSON
        if rows and isinstance(rows[0], dict):
            columns = columns or list(rows[0])
            body = [[r.get(c, "") for c in columns] for r in rows]
        else:
            body = [list(r) for r in rows]
            columns = list(columns or [])
        self.tables[name] = {"columns": columns, "labels": [label(c) for c in columns], "rows": body,
                             "caption": caption}
        self._blocks.append(("table", (name, columns, body, caption, fmt)))

    def add_figure(self, name, fig, data=None, caption="", dpi=90):
        """A matplotlib figure (rendered to PNG now, then closed) with the data it shows."""
        import matplotlib.pyplot as plt
        name = _unique(name, self.figures)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
        plt.close(fig)
        png = base64.b64encode(buf.getvalue()).decode("ascii")
        labels = [{"xlabel": a.get_xlabel(), "ylabel": a.get_ylabel()} for a in fig.axes
                  if a.get_label() != "<colorbar>"]
        self.figures[name] = {"caption": caption, "data": data or {}, "axes": labels}
        self._blocks.append(("figure", (name, png, caption)))

    def add_data(self, name, data):
        """Extra JSON data (not shown in the HTML body)."""
        self.extra[name] = data

    # ----------------------------------------------------------------- output
    def to_dict(self):
        return _jsonable({"title": self.title, "meta": self.meta, "tables": self.tables,
                          "figures": self.figures, "data": self.extra})

    def html(self):
        out = ["<!DOCTYPE html>", "<html lang='en'><head><meta charset='utf-8'>",
               f"<title>{html.escape(self.title)}</title><style>{_CSS}</style></head><body>",
               f"<h1>{html.escape(self.title)}</h1>"]
        if self.meta:
            out.append("<p class='meta'>" + " · ".join(f"{html.escape(str(k))}: {html.escape(str(v))}"
                                                     for k, v in self.meta.items()) + "</p>")
        for kind, p in self._blocks:
            if kind == "heading":
                lvl, text = p
                out.append(f"<h{lvl}>{html.escape(text)}</h{lvl}>")
            elif kind == "text":
                for para in p.split("\n\n"):
                    out.append(f"<p>{html.escape(para)}</p>")
            elif kind == "code":
                out.append(f"<pre>{html.escape(p)}</pre>")
            elif kind == "table":
                name, cols, body, caption, fmt = p
                out.append(f"<div class='table-wrap'><table id='table-{html.escape(name)}'>")
                if caption:
                    out.append(f"<caption>{html.escape(caption)}</caption>")
                if cols:
                    out.append("<tr>" + "".join(f"<th>{html.escape(label(c))}</th>" for c in cols) + "</tr>")
                for row in body:
                    out.append("<tr>" + "".join(f"<td>{html.escape(_cell(v, fmt))}</td>" for v in row) + "</tr>")
                out.append("</table></div>")
            elif kind == "figure":
                name, png, caption = p
                out.append(f"<figure id='figure-{html.escape(name)}'><img alt='{html.escape(name)}' "
                           f"src='data:image/png;base64,{png}'>")
                if caption:
                    out.append(f"<figcaption>{html.escape(caption)}</figcaption>")
                out.append("</figure>")
        # every '<' escaped: no user text (a file name, a port description) can end the script
        # element or open a comment in it (JSON reads \u003c back as '<')
        data = json.dumps(self.to_dict()).replace("<", "\\u003c")
        out.append(f"<script type='application/json' id='report-data'>{data}</script>")
        out.append("</body></html>")
        # a file name that is not UTF-8 reaches Python as lone surrogates ('\udcff'): escaped as
        # the command line prints it, so that every writer can encode the page
        return "\n".join(out).encode("utf-8", "backslashreplace").decode("utf-8")

    def write(self, path):
        """Write the self-contained HTML file atomically (``outputs.atomic_write``: a symlink at
        ``path`` is replaced, never followed); returns its Path."""
        return atomic_write(path, self.html())

    def write_json(self, path):
        return atomic_write(path, json.dumps(self.to_dict(), indent=1))


def _unique(name, taken):
    """``name``, or ``name_2``, ``name_3``... when a table or figure of that name exists."""
    base, k = str(name), 2
    name = base
    while name in taken:
        name, k = f"{base}_{k}", k + 1
    return name


def _cell(v, fmt):
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (float, np.floating)):
        if not np.isfinite(v):
            return "–"
        if fmt == _FMT and 1e3 <= abs(v) < 1e6:      # 6000 mm/min, not 6e+03
            return f"{float(v):.0f}"
        return fmt.format(float(v))
    return str(v)


def decimate(x, n_max=4000):
    """Every k-th sample so that at most ``n_max`` remain (for figure data)."""
    x = np.asarray(x)
    k = max(1, int(np.ceil(x.size / n_max)))
    return x[::k]


def add_model_section(rep, model, fmu=None, validation=None, heading="The identified model"):
    """Add what an engineer looks for first: the identified model itself.

    Sample time, structure (states, inputs, outputs, method), continuous poles in Hz with their
    damping, friction parameters, training fit, a Bode plot (command -> tracking error and
    position per axis) and a pole-zero map of the linear part from python-control
    (:meth:`~fdid_fmi.model.DriveModel.to_control`), and, when given, the FMU's variables and
    its validation status.

    Parameters
    ----------
    rep : Report
    model : DriveModel or QuasiStaticModel
    fmu : path of the exported FMU, optional
    validation : dict, optional   e.g. ``ValidationResult.to_dict()`` (``problems``,
        ``max_abs_diff_reference_mm``, per-axis discrepancy)
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from .model import QuasiStaticModel
    rep.add_heading(heading)
    if isinstance(model, QuasiStaticModel):
        rows = [{"axis": a, "K_vel [ms]": g["K_vel"] * 1e3, "K_acc [ms^2]": g["K_acc"] * 1e6,
                 "K_jerk [ms^3]": g["K_jerk"] * 1e9} for a, g in model.gains.items()]
        rep.add_text(f"Quasi-static model (thesis Eqn 3.4), Ts = {model.Ts * 1e3:.4g} ms: the tracking "
                     "error is predicted as K_vel times the commanded velocity plus K_acc times the "
                     "acceleration plus K_jerk times the jerk. K_vel is the lag in time (1/Kp for a "
                     "P position loop).")
        rep.add_table("model_gains", rows, caption="quasi-static gains per axis")
        return
    ins = ", ".join(f"{p.name} [{p.unit}] ({p.kind})" for p in model.inputs)
    outs = ", ".join(f"{p.name} [{p.unit}] ({p.kind})" for p in model.outputs)
    rep.add_text(
        f"Method: {model.method or 'state space'}; sample time Ts = {model.Ts * 1e3:.6g} ms; "
        f"{model.n_states} states; inputs: {ins}; outputs: {outs}. The linear part is a discrete "
        "state space (A, B, C, D) at Ts; the friction inputs close a loop around it through the "
        "model's own velocity (d = L sat(v / v_tilde), solved exactly at each step). Poles are the "
        "continuous closed-loop poles the search found: their frequency says how fast the axis "
        "answers, the damping ratio how much it rings (1 = no overshoot, small = a resonance).")
    rows = []
    for p in model.poles:
        w = abs(p)
        rows.append({"pole [rad/s]": f"{p.real:.4g}{p.imag:+.4g}j" if p.imag else f"{p.real:.4g}",
                     "frequency [Hz]": w / (2 * np.pi),
                     "damping ratio [-]": (-p.real / w) if w > 0 else float("nan"),
                     "time constant [ms]": (-1e3 / p.real) if p.real < 0 else float("inf")})
    if rows:
        rep.add_table("model_poles", rows, caption="continuous poles of the identified model")
    fr = [{"input": p.name, "axis": p.axis, "v_tilde [mm/s]": p.params.get("v_tilde", float("nan")),
           "level L [-]": p.params.get("level", 1.0)} for p in model.inputs if p.kind == "friction"]
    if fr:
        rep.add_table("model_friction", fr, caption="friction: normalised Coulomb input d = L sat(v / v_tilde) "
                      "(Eqn 4.12-4.13); its force scale is in the numerator (d0) of each output")
    fit = metric_rows(model)
    if fit:
        rep.add_table("model_fit", fit, columns=["part", "quantity", "value"],
                      caption="training fit as the identification recorded it: the residual of the "
                              "least-squares fit on the training trace, with the friction term built from the "
                              "measured velocity (the free-run discrepancy of the validation is what the twin "
                              "is judged by)")
    if model.effects:
        rep.add_table("model_effects", [{"kind": e.get("kind", "?"), "axis": e.get("axis", ""),
                                         "parameters": ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                                                 for k, v in e.items() if k not in ("kind", "axis"))}
                                        for e in model.effects], caption="effects added by diagnosis")
    # Bode plot and pole-zero map from python-control
    try:
        sys_ = model.to_control()
    except Exception as exc:  # noqa: BLE001 - the report still shows the tables
        rep.add_text(f"No Bode plot: python-control could not take the model ({exc}).")
        sys_ = None
    if sys_ is not None:
        import control
        f_hz = np.logspace(-1, np.log10(0.45 / model.Ts), 300)
        w = 2 * np.pi * f_hz
        fig, (am, ph) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
        data = {"f_hz": f_hz}
        for ax in model.axes:
            i = model.input_index("command", ax)
            for kind in ("error", "position"):
                o = model.output_index(kind, ax)
                if o is None:
                    continue
                resp = control.frequency_response(sys_[o, i], w)
                H = np.squeeze(resp.complex)
                mag = 20 * np.log10(np.maximum(np.abs(H), 1e-300))
                phase = np.degrees(np.unwrap(np.angle(H)))
                lab = f"{ax}: {model.inputs[i].name} -> {model.outputs[o].name}"
                am.semilogx(f_hz, mag, label=lab)
                ph.semilogx(f_hz, phase, label=lab)
                data[f"{model.outputs[o].name}_mag_db"] = mag
                data[f"{model.outputs[o].name}_phase_deg"] = phase
        am.set_ylabel("magnitude [dB]")
        ph.set_ylabel("phase [deg]")
        ph.set_xlabel("frequency [Hz]")
        am.grid(alpha=0.3, which="both")
        ph.grid(alpha=0.3, which="both")
        am.legend(fontsize=7)
        rep.add_figure("model_bode", fig, data=data,
                       caption="Bode plot of the linear part (python-control, discrete at Ts): commanded "
                               "position to tracking error and to position per axis; friction not included")
        poles = sys_.poles()
        try:
            zeros = sys_.zeros()
        except Exception:  # noqa: BLE001 - MIMO zeros need slycot; show poles only
            zeros = np.array([])
        fig, (ax2, ax3) = plt.subplots(1, 2, figsize=(11, 5))
        th = np.linspace(0, 2 * np.pi, 400)
        ax2.plot(np.cos(th), np.sin(th), "k:", lw=0.8)
        ax2.plot(poles.real, poles.imag, "x", ms=9, label="poles")
        if zeros.size:
            ax2.plot(zeros.real, zeros.imag, "o", mfc="none", ms=8, label="zeros")
        ax2.set_xlabel("Re z [-]")
        ax2.set_ylabel("Im z [-]")
        ax2.set_aspect("equal")
        ax2.legend(fontsize=8)
        ax2.grid(alpha=0.3)
        ax2.set_title("z plane (unit circle: stability limit)", fontsize=9)

        def to_hz(z):
            z = np.asarray(z, complex)
            keep = (np.abs(z) > 1e-6) & ~((np.abs(z.imag) < 1e-12) & (z.real < 0))
            return np.log(z[keep]) / model.Ts / (2 * np.pi)

        ps, zs = to_hz(poles), to_hz(zeros)
        reach = 3 * max(np.max(np.abs(ps)) if ps.size else 1.0, 1e-9)
        n_far = int(np.sum(np.abs(zs) > reach))
        zs = zs[np.abs(zs) <= reach]                 # fast zeros far left would hide the poles
        ax3.plot(ps.real, ps.imag, "x", ms=9, label="poles")
        if zs.size:
            ax3.plot(zs.real, zs.imag, "o", mfc="none", ms=8, label="zeros")
        ax3.axvline(0, color="k", lw=0.8, ls=":")
        ax3.set_xlabel("Re s / 2π [Hz]")
        ax3.set_ylabel("Im s / 2π [Hz]")
        ax3.legend(fontsize=8)
        ax3.grid(alpha=0.3)
        ax3.set_title("the same, mapped to continuous time, s = ln(z) / Ts", fontsize=9)
        rep.add_figure("model_pzmap", fig, data={"poles_re": poles.real, "poles_im": poles.imag,
                                                 "zeros_re": np.real(zeros), "zeros_im": np.imag(zeros),
                                                 "poles_s_re_hz": ps.real, "poles_s_im_hz": ps.imag},
                       caption="pole-zero map of the linear part (python-control): left in the z plane "
                               "(inside the unit circle = stable), right mapped to continuous time in Hz "
                               "(left of the dotted line = stable; the distance from the origin is the "
                               "pole's frequency). Delay poles at z = 0 and zeros on the negative real "
                               "axis have no continuous equivalent and are left out on the right"
                               + (f", as are {n_far} zero(s) more than 3x farther out than the fastest pole."
                                  if n_far else "."))
    if fmu is not None:
        _fmu_variables(rep, fmu)
    if validation is not None:
        probs = validation.get("problems", [])
        diff = validation.get("max_abs_diff_reference_mm")
        rep.add_text("FMU validation: " + ("no problems" if not probs else f"{len(probs)} problem(s): "
                                           + "; ".join(map(str, probs[:5])))
                     + (f"; largest |FMU - reference simulator| = {diff:.3g} mm" if diff is not None else "")
                     + ". The FMU is the model compiled to C; it must reproduce the reference simulator.")


def metric_rows(model, limit=40):
    """The model's training record (``model.metrics``) as rows {part, quantity, value}, labelled
    from :data:`fdid_fmi.labels.LABELS` with each value in the label's unit. ``part`` names the
    axes of each block of a combined per-axis model (from the outputs its figures are of)."""
    m = model.metrics if isinstance(model.metrics, dict) else {}
    blocks = m["blocks"] if isinstance(m.get("blocks"), list) else [m]
    axis_of = {p.name: p.axis for p in getattr(model, "outputs", [])}
    rows = []
    for i, blk in enumerate(blocks, 1):
        if not isinstance(blk, dict):
            continue
        outs = blk.get("fit_rms") if isinstance(blk.get("fit_rms"), dict) else {}
        axes = sorted({axis_of[o] for o in outs if axis_of.get(o)})
        part = (("axis " if len(axes) == 1 else "axes ") + ", ".join(axes) if axes
                else f"block {i}" if len(blocks) > 1 else "model")
        for key, value in blk.items():
            if isinstance(value, dict):
                rows += [{"part": part, "quantity": metric_label(key, o), "value": _scaled(key, v)}
                         for o, v in value.items() if _number(v)]
            elif _number(value):
                rows.append({"part": part, "quantity": metric_label(key), "value": _scaled(key, value)})
    return rows[:limit]


def _number(v):
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _scaled(key, v):
    t = LABELS.get(key)
    return v if isinstance(v, (int, np.integer)) or t is None or t.scale == 1.0 else float(v) * t.scale


def _fmu_variables(rep, fmu):
    try:
        from fmpy import read_model_description
        from .fmu.archive import check_fmu_archive
        check_fmu_archive(fmu)              # member paths and sizes, before fmpy inflates it
        md = read_model_description(str(fmu))
    except Exception as exc:  # noqa: BLE001
        rep.add_text(f"FMU {fmu}: its model description could not be read ({exc}).")
        return
    rows = [{"name": v.name, "causality": v.causality, "variability": v.variability,
             "type": v.type, "unit": getattr(v, "unit", "") or "", "start": v.start if v.start is not None else "",
             "description": v.description or ""} for v in md.modelVariables]
    ex = md.defaultExperiment
    rep.add_text(f"FMU {Path(str(fmu)).name}: FMI {md.fmiVersion} co-simulation, model identifier "
                 f"{md.coSimulation.modelIdentifier if md.coSimulation else '?'}"
                 + (f", step size {ex.stepSize} s" if ex is not None and ex.stepSize else "") + ".")
    rep.add_table("fmu_variables", rows, caption="FMU variables (inputs: commanded positions; outputs: "
                  "predicted position and velocity, ...; parameters: friction level, v_tilde, ...). The "
                  "tracking error at a time t is the command of t minus <axis>_x read for t "
                  "(docs/fmu-interface.md)")
