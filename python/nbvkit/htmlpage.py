"""The pieces of nbvkit's self-contained HTML pages (a run's report.html, an experiment's):
plotly.js inlined, the page, plots, images, tables, numbers, written whole."""
from __future__ import annotations

import base64
import functools
import html
import json
from pathlib import Path

import numpy as np

from .output_paths import write_text_atomic

__all__ = [
    "plotly_js",
    "page",
    "plot_div",
    "img",
    "fmt",
    "table",
    "rounded",
    "plain",
    "write_text",
]


@functools.lru_cache(maxsize=1)
def plotly_js() -> str:
    """plotly.js, from the plotly package (Debian's python3-plotly reads it from
    /usr/share/python3-plotly/plotly.js), read once per process (3.6 MB: a sweep's worker writes
    a report per run). Raises RuntimeError if plotly is not installed."""
    try:
        from plotly.offline import get_plotlyjs

        return get_plotlyjs()
    except Exception:  # noqa: BLE001 - fall back to Debian's file
        p = Path("/usr/share/python3-plotly/plotly.js")
        if p.exists():
            return p.read_text()
        raise RuntimeError(
            "report.html needs plotly.js: install Debian's python3-plotly (make deps)"
        ) from None


@functools.lru_cache(maxsize=1)
def _plotly_in_script() -> str:
    """plotly_js() as the body of an HTML script element."""
    return plotly_js().replace("</script", "<\\/script")


_STYLE = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1250px; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em 0; font-size: 0.9em; }
td, th { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f2f2f2; } td:first-child, th:first-child { text-align: left; }
img { max-width: 100%; border: 1px solid #eee; } h2 { margin-top: 1.5em; }
.plot { width: 100%; height: 700px; } .small { height: 380px; }
"""


def page(title: str, body: str, plotly: bool = True) -> str:
    """A whole HTML page: `body` with the style, and plotly.js inlined unless plotly=False."""
    js = _plotly_in_script() if plotly else ""
    script = f"<script type='text/javascript'>{js}</script>" if plotly else ""
    return (
        "<!DOCTYPE html>\n<html><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{_STYLE}</style>"
        f"{script}</head><body>\n{body}\n</body></html>\n"
    )


def script_json(value) -> str:
    """JSON written inside a <script> element: its <, > and & as JavaScript escapes, so that no
    string in it (a plugin's name, a file's) can end the element or open another."""
    text = json.dumps(value, separators=(",", ":"), allow_nan=False)
    return text.replace("&", "\\u0026").replace("<", "\\u003c").replace(">", "\\u003e")


def plot_div(div: str, traces: list, layout: dict, cls: str = "plot") -> str:
    """A plotly figure (traces, layout) in the element `div` of class `cls`."""
    data, lay = script_json(traces), script_json(layout)
    return (
        f"<div id='{div}' class='{cls}'></div><script>Plotly.newPlot('{div}', {data}, {lay}, "
        "{responsive: true});</script>"
    )


def img(path: Path) -> str:
    """The PNG at path, inlined."""
    b = base64.b64encode(Path(path).read_bytes()).decode()
    return f"<p><img alt='{html.escape(Path(path).name)}' src='data:image/png;base64,{b}'></p>"


def fmt(v) -> str:
    """A table cell's text: floats to 4 significant digits, anything else escaped."""
    if isinstance(v, float):
        return f"{v:.4g}"
    return html.escape(str(v))


def table(rows: list[tuple]) -> str:
    """An HTML table of rows (fmt cells)."""
    out = ["<table>"]
    for r in rows:
        out.append("<tr>" + "".join(f"<td>{fmt(x)}</td>" for x in r) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def rounded(a, nd=3):
    """a as a list of floats rounded to nd decimals (a plotly trace's numbers)."""
    return np.round(np.asarray(a, float), nd).tolist()


def write_text(path, text: str) -> None:
    """Writes the page whole (nbvkit.output_paths.write_text_atomic)."""
    write_text_atomic(Path(path), text)


def plain(v):
    """A numpy scalar as a Python number (anything else as it is)."""
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, (np.integer,)):
        return int(v)
    return v
