"""Self-contained HTML reports: text, tables and matplotlib figures (PNG embedded as base64),
plus a JSON of every figure's data, so a reader can replot or check any number.

    rep = Report("Diagnosis of model.json")
    rep.add_text("What was found ...", heading="Summary")
    rep.add_table("errors", rows, columns=["trace", "axis", "RMS [µm]"], caption="...")
    fig, ax = plt.subplots(); ax.plot(t, r)
    rep.add_figure("residual", fig, data={"t_s": t, "residual_um": r}, caption="...")
    rep.write("report.html")              # one file, no external resources
    rep.write_json("report.json")         # every table and figure's data

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

from .model import jsonable

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;
margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #444;padding-bottom:.2em}
h2{font-size:1.25em;margin-top:1.8em;border-bottom:1px solid #bbb}
h3{font-size:1.05em}
table{border-collapse:collapse;margin:.6em 0 1.2em 0;font-size:.92em}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}
figure{margin:1em 0}figcaption{font-size:.9em;color:#555}
img{max-width:100%}
.meta{color:#666;font-size:.85em}
pre{background:#f6f6f6;padding:.6em;overflow-x:auto;font-size:.85em}
"""


_jsonable = jsonable  # one definition, in model.py


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

    def add_table(self, name, rows, columns=None, caption="", fmt="{:.3g}"):
        """A table. ``rows``: list of dicts (``columns`` picks and orders the keys) or of lists."""
        if rows and isinstance(rows[0], dict):
            columns = columns or list(rows[0])
            body = [[r.get(c, "") for c in columns] for r in rows]
        else:
            body = [list(r) for r in rows]
            columns = list(columns or [])
        self.tables[name] = {"columns": columns, "rows": body, "caption": caption}
        self._blocks.append(("table", (name, columns, body, caption, fmt)))

    def add_figure(self, name, fig, data=None, caption="", dpi=90):
        """A matplotlib figure (rendered to PNG now, then closed) with the data it shows."""
        import matplotlib.pyplot as plt
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
        plt.close(fig)
        png = base64.b64encode(buf.getvalue()).decode("ascii")
        self.figures[name] = {"caption": caption, "data": data or {}}
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
                out.append(f"<table id='table-{html.escape(name)}'>")
                if caption:
                    out.append(f"<caption>{html.escape(caption)}</caption>")
                if cols:
                    out.append("<tr>" + "".join(f"<th>{html.escape(str(c))}</th>" for c in cols) + "</tr>")
                for row in body:
                    out.append("<tr>" + "".join(f"<td>{html.escape(_cell(v, fmt))}</td>" for v in row) + "</tr>")
                out.append("</table>")
            elif kind == "figure":
                name, png, caption = p
                out.append(f"<figure id='figure-{html.escape(name)}'><img alt='{html.escape(name)}' "
                           f"src='data:image/png;base64,{png}'>")
                if caption:
                    out.append(f"<figcaption>{html.escape(caption)}</figcaption>")
                out.append("</figure>")
        data = json.dumps(self.to_dict()).replace("</", "<\\/")
        out.append(f"<script type='application/json' id='report-data'>{data}</script>")
        out.append("</body></html>")
        return "\n".join(out)

    def write(self, path):
        """Write the self-contained HTML file; returns its Path."""
        path = Path(path)
        path.write_text(self.html(), encoding="utf-8")
        return path

    def write_json(self, path):
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1), encoding="utf-8")
        return path


def _cell(v, fmt):
    if isinstance(v, (float, np.floating)):
        return fmt.format(float(v)) if np.isfinite(v) else "–"
    return str(v)


def decimate(x, n_max=4000):
    """Every k-th sample so that at most ``n_max`` remain (for figure data)."""
    x = np.asarray(x)
    k = max(1, int(np.ceil(x.size / n_max)))
    return x[::k]
