"""Self-contained HTML report pages: sections with a plain-language reading, tables and figures.

A :class:`Report` is a list of :class:`Section` objects.  Each section holds

* ``reading``: a short plain-language paragraph computed from the section's numbers;
* ``tables``: named :class:`pandas.DataFrame` objects (rendered as HTML tables, also written as
  CSV next to the page);
* ``figures``: named matplotlib figures, converted to PNG at once (the figure is closed) and
  embedded in the page as ``data:image/png;base64`` URIs, so the page needs no other file, no
  network and no JavaScript;
* ``error``: the error of a step that failed (shown in its section instead of killing the page);
* ``placeholder``: set while a step cannot run yet (its API missing); a placeholder is never a
  finished result and :attr:`Report.ok` is False while one is present.

:meth:`Report.write` writes ``DIR/index.html``, ``DIR/tables/<section>__<table>.csv``,
``DIR/figures/<section>__<figure>.png`` and ``DIR/manifest.json`` (every table and figure the
page claims, with its file, the section's status and timing).

>>> import pandas as pd
>>> rep = Report("Example")
>>> sec = rep.add(Section("fit", "A fit", reading="The line fits."))
>>> sec.add_table("params", pd.DataFrame({"a": [1.0], "b": [2.0]}))
>>> "<table" in rep.to_html()
True
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["Report", "Section", "figure_png", "fmt"]

_SLUG = re.compile(r"[^a-z0-9_]+")


def slug(text: str) -> str:
    """A file-name-safe lower-case key (``"Leave-one-cycle out"`` -> ``"leave_one_cycle_out"``)."""
    s = _SLUG.sub("_", str(text).strip().lower()).strip("_")
    if not s:
        raise ValueError(f"cannot make a key from {text!r}: it has no letters or digits")
    return s


def fmt(x: Any, digits: int = 4) -> str:
    """Format a number with ``digits`` significant digits (integers as they are, NaN as 'n/a')."""
    if isinstance(x, (bool, np.bool_)):
        return str(bool(x))
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    try:
        v = float(x)
    except (TypeError, ValueError):
        return str(x)
    if math.isnan(v):
        return "n/a"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return f"{v:.{digits}g}"


def figure_png(fig, *, dpi: int = 110, close: bool = True) -> bytes:
    """PNG bytes of a matplotlib figure (closed afterwards unless ``close=False``)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    if close:
        import matplotlib.pyplot as plt

        plt.close(fig)
    data = buf.getvalue()
    if not data.startswith(b"\x89PNG"):
        raise ValueError("matplotlib did not produce a PNG image")
    return data


@dataclass
class Section:
    """One step of a report: a reading, tables and figures, or the step's error.

    ``key`` names the files of the section's tables and figures; ``title`` is its heading.
    """

    key: str
    title: str
    reading: str = ""
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    figures: dict[str, bytes] = field(default_factory=dict)
    captions: dict[str, str] = field(default_factory=dict)
    error: str | None = None
    placeholder: bool = False
    seconds: float | None = None
    cpu_seconds: float | None = None
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.key = slug(self.key)

    @property
    def status(self) -> str:
        """``"error"``, ``"placeholder"`` or ``"ok"``."""
        if self.error is not None:
            return "error"
        if self.placeholder:
            return "placeholder"
        return "ok"

    def add_table(self, name: str, df: pd.DataFrame, caption: str = "") -> pd.DataFrame:
        """Add a table (a copy with a flat column index and string column names)."""
        if not isinstance(df, pd.DataFrame):
            raise ValueError(f"table {name!r} must be a pandas DataFrame, got {type(df).__name__}")
        out = df.copy()
        if isinstance(out.columns, pd.MultiIndex):
            out.columns = ["_".join(str(c) for c in col if str(c)) for col in out.columns]
        out.columns = [str(c) for c in out.columns]
        key = slug(name)
        if key in self.tables:
            raise ValueError(f"section {self.key!r} already has a table {key!r}")
        self.tables[key] = out
        if caption:
            self.captions[f"table:{key}"] = caption
        return out

    def add_figure(self, name: str, fig, caption: str = "") -> None:
        """Add a matplotlib figure (stored as PNG bytes; the figure is closed) or PNG bytes."""
        key = slug(name)
        if key in self.figures:
            raise ValueError(f"section {self.key!r} already has a figure {key!r}")
        self.figures[key] = fig if isinstance(fig, bytes) else figure_png(fig)
        if caption:
            self.captions[f"figure:{key}"] = caption


def _table_html(df: pd.DataFrame, max_rows: int) -> str:
    shown = df if len(df) <= max_rows else df.head(max_rows)
    index = not isinstance(shown.index, pd.RangeIndex)
    body = shown.to_html(
        index=index,
        border=0,
        classes="data",
        na_rep="n/a",
        float_format=lambda v: fmt(v),
        escape=True,
    )
    body = f'<div class="scroll">{body}</div>'
    if len(df) > max_rows:
        body += f'<p class="more">First {max_rows} of {len(df)} rows; the CSV file has them all.</p>'
    return body


_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Helvetica, Arial, sans-serif;
       max-width: 1100px; margin: 0 auto; padding: 1.2em; color: #1d1d1f; line-height: 1.45; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: 0.2em;
     margin-top: 2em; }
.banner { padding: 0.6em 0.9em; margin: 0.5em 0; border-radius: 4px; background: #fff4ce;
          border: 1px solid #e0c060; }
.synthetic { background: #e8f0fe; border-color: #7aa0e0; }
.reading { font-size: 1.05em; background: #f6f8fa; border-left: 4px solid #4a7; padding: 0.6em 0.9em; }
.error { background: #fde8e8; border: 1px solid #d66; padding: 0.6em 0.9em; white-space: pre-wrap;
         font-family: ui-monospace, monospace; font-size: 0.9em; }
.placeholder { background: #fff0e0; border: 1px dashed #d90; padding: 0.6em 0.9em; }
.scroll { overflow-x: auto; max-width: 100%; }
table.data { border-collapse: collapse; font-size: 0.85em; margin: 0.5em 0 1em 0; }
table.data th, table.data td { padding: 0.2em 0.6em; border-bottom: 1px solid #ddd; text-align: right; }
table.data th { background: #f0f0f0; }
figure { margin: 0.8em 0; } figure img { max-width: 100%; height: auto; border: 1px solid #eee; }
figcaption, .caption { font-size: 0.9em; color: #555; }
.meta, .more { font-size: 0.85em; color: #666; }
nav ol { columns: 2; font-size: 0.95em; }
.status-error { color: #b00; } .status-placeholder { color: #b60; } .status-ok { color: #070; }
"""


@dataclass
class Report:
    """A page of sections, written as one self-contained HTML file plus CSV tables.

    ``banners`` are notices shown at the top (e.g. "quick run", "synthetic data"), ``meta``
    key/value facts about the run (seed, version, timings).
    """

    title: str
    intro: str = ""
    banners: list[tuple[str, str]] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)
    sections: list[Section] = field(default_factory=list)
    max_rows: int = 30

    def add(self, section: Section) -> Section:
        if any(s.key == section.key for s in self.sections):
            raise ValueError(f"the report already has a section {section.key!r}")
        self.sections.append(section)
        return section

    def banner(self, text: str, kind: str = "note") -> None:
        """Add a notice at the top of the page (``kind`` is a CSS class: note, synthetic)."""
        self.banners.append((kind, text))

    @property
    def ok(self) -> bool:
        """True when every section finished (no error, no placeholder)."""
        return all(s.status == "ok" for s in self.sections)

    # --- rendering -----------------------------------------------------------------------
    def to_html(self) -> str:
        e = html.escape
        parts = [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            f"<title>{e(self.title)}</title><style>{_CSS}</style></head><body>",
            f"<h1>{e(self.title)}</h1>",
        ]
        for kind, text in self.banners:
            parts.append(f'<div class="banner {e(slug(kind))}">{e(text)}</div>')
        if self.intro:
            parts.append(f"<p>{e(self.intro)}</p>")
        if self.meta:
            facts = "; ".join(f"{e(str(k))}: {e(fmt(v) if not isinstance(v, str) else v)}"
                              for k, v in self.meta.items())
            parts.append(f'<p class="meta">{facts}</p>')
        parts.append("<nav><ol>")
        for s in self.sections:
            parts.append(
                f'<li><a href="#{s.key}">{e(s.title)}</a> '
                f'<span class="status-{s.status}">({s.status})</span></li>'
            )
        parts.append("</ol></nav>")
        for s in self.sections:
            parts.append(self._section_html(s))
        parts.append("</body></html>")
        return "\n".join(parts)

    def _section_html(self, s: Section) -> str:
        e = html.escape
        out = [f'<section id="{s.key}"><h2>{e(s.title)}</h2>']
        if s.seconds is not None:
            cpu = f" (CPU {s.cpu_seconds:.1f} s)" if s.cpu_seconds is not None else ""
            out.append(f'<p class="meta">Step time: {s.seconds:.1f} s{cpu}</p>')
        if s.placeholder:
            out.append(
                '<div class="placeholder"><strong>Placeholder</strong>: this step is not computed '
                "by the real workflow yet; its content below is not a result.</div>"
            )
        if s.error is not None:
            out.append(f'<p><strong>This step failed</strong>; the rest of the page is unaffected.</p>'
                       f'<div class="error">{e(s.error)}</div>')
        if s.reading:
            paras = "".join(f"<p>{e(p)}</p>" for p in s.reading.split("\n\n") if p.strip())
            out.append(f'<div class="reading">{paras}</div>')
        for note in s.notes:
            out.append(f"<p>{e(note)}</p>")
        for name, df in s.tables.items():
            cap = s.captions.get(f"table:{name}", "")
            out.append(f'<h3>Table: {e(name)}</h3>')
            if cap:
                out.append(f'<p class="caption">{e(cap)}</p>')
            out.append(_table_html(df, self.max_rows))
        for name, png in s.figures.items():
            cap = s.captions.get(f"figure:{name}", "")
            b64 = base64.b64encode(png).decode("ascii")
            out.append(
                f'<figure><img alt="{e(name)}" src="data:image/png;base64,{b64}">'
                f"<figcaption>{e(name)}{': ' + e(cap) if cap else ''}</figcaption></figure>"
            )
        out.append("</section>")
        return "\n".join(out)

    # --- files ---------------------------------------------------------------------------
    def manifest(self) -> dict[str, Any]:
        """What the page claims: every section with its status, tables and figures."""
        secs = []
        for s in self.sections:
            secs.append(
                {
                    "key": s.key,
                    "title": s.title,
                    "status": s.status,
                    "error": s.error,
                    "seconds": s.seconds,
                    "cpu_seconds": s.cpu_seconds,
                    "reading": s.reading,
                    "tables": [
                        {
                            "name": name,
                            "csv": f"tables/{s.key}__{name}.csv",
                            "rows": len(df),
                            "columns": list(df.columns),
                        }
                        for name, df in s.tables.items()
                    ],
                    "figures": [
                        {"name": name, "png": f"figures/{s.key}__{name}.png", "embedded": True}
                        for name in s.figures
                    ],
                }
            )
        return {
            "title": self.title,
            "page": "index.html",
            "ok": self.ok,
            "banners": [text for _, text in self.banners],
            "meta": {k: (v if isinstance(v, (str, int, float, bool)) or v is None else str(v))
                     for k, v in self.meta.items()},
            "sections": secs,
        }

    def write(self, out_dir: str | Path) -> Path:
        """Write ``index.html``, ``tables/*.csv``, ``figures/*.png`` and ``manifest.json``.

        Returns the path of ``index.html``.  Existing files of the same names are replaced.
        """
        out = Path(out_dir)
        if out.exists() and not out.is_dir():
            raise ValueError(f"report folder {str(out)!r} exists and is not a folder")
        (out / "tables").mkdir(parents=True, exist_ok=True)
        (out / "figures").mkdir(parents=True, exist_ok=True)
        for s in self.sections:
            for name, df in s.tables.items():
                index = not isinstance(df.index, pd.RangeIndex)
                df.to_csv(out / "tables" / f"{s.key}__{name}.csv", index=index)
            for name, png in s.figures.items():
                (out / "figures" / f"{s.key}__{name}.png").write_bytes(png)
        page = out / "index.html"
        page.write_text(self.to_html(), encoding="utf-8")
        (out / "manifest.json").write_text(json.dumps(self.manifest(), indent=2), encoding="utf-8")
        return page
