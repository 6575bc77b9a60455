"""The batch's summary: one row per input, in ``summary.csv`` as results arrive and in ``summary.html`` at the end."""

from __future__ import annotations

import csv
import html
import io
import os
import posixpath
import time
from dataclasses import astuple, dataclass, fields

from ._inputs import PREVIEW_SUFFIX, fs_of, is_local

__all__ = ["BatchRow", "SummaryWriter", "write_html", "STATUSES"]

#: Row statuses, failures first: the order of the HTML table.
STATUSES = ("error", "invalid", "ok", "skipped")


@dataclass(frozen=True)
class BatchRow:
    """One input's line of the summary.

    Attributes
    ----------
    input : str
        The mesh (a path or an fsspec URL).
    output : str
        The written shape ("" when nothing was written).
    status : str
        ``ok`` (recon's verdict on the result is good), ``invalid`` (written, not good), ``error`` (nothing
        written: unreadable input, crash, timeout, memory) or ``skipped`` (an earlier run made it, good, with the
        same recon and options).
    faces : int or None
    valid : bool or None
        A valid closed solid.
    mesh_to_shape_p95_pct : float or None
        95th percentile of the mesh's distance to the shape, % of the bounding-box diagonal.
    seconds : float
        Wall time of the part on its worker (0 when skipped).
    message : str
        One line: why it failed or is not good, and a renaming.
    """

    input: str
    output: str
    status: str
    faces: int | None
    valid: bool | None
    mesh_to_shape_p95_pct: float | None
    seconds: float
    message: str


COLUMNS = [f.name for f in fields(BatchRow)]


def _csv_line(values) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(["" if v is None else v for v in values])
    return buf.getvalue()


class SummaryWriter:
    """``summary.csv``, a row appended and flushed as each part finishes, so a client that dies loses no finished
    row. On a store without appends (object stores, memory) the file is rewritten whole, at most every
    ``every`` seconds and at :meth:`close`."""

    def __init__(self, out: str, *, every: float = 10.0):
        self.fs, root = fs_of(out)
        self.path = posixpath.join(root, "summary.csv")
        self.every, self.last = every, 0.0
        self.rows: list[BatchRow] = []
        self.fh = open(self.path, "w", newline="") if is_local(self.fs) else None
        self._write(_csv_line(COLUMNS))

    def _write(self, text: str) -> None:
        if self.fh is not None:
            self.fh.write(text)
            self.fh.flush()

    def add(self, row: BatchRow) -> None:
        self.rows.append(row)
        self._write(_csv_line(astuple(row)))
        if self.fh is None and time.monotonic() - self.last >= self.every:
            self._rewrite()

    def _rewrite(self) -> None:
        with self.fs.open(self.path, "w") as fh:
            fh.write("".join(_csv_line(r) for r in [COLUMNS, *map(astuple, self.rows)]))
        self.last = time.monotonic()

    def close(self) -> None:
        if self.fh is not None:
            self.fh.close()
        else:
            self._rewrite()


def _fmt(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


_SCRIPT = """
document.querySelectorAll('th').forEach((th, col) => th.addEventListener('click', () => {
  const body = th.closest('table').tBodies[0], rows = Array.from(body.rows);
  const dir = th.dataset.dir = th.dataset.dir === 'asc' ? 'desc' : 'asc';
  const key = r => { const t = r.cells[col].dataset.v ?? r.cells[col].textContent, n = parseFloat(t);
                     return t !== '' && !isNaN(n) && isFinite(t) ? n : t; };
  rows.sort((a, b) => { const x = key(a), y = key(b);
    const c = typeof x === typeof y ? (x < y ? -1 : x > y ? 1 : 0) : (typeof x === 'number' ? -1 : 1);
    return dir === 'asc' ? c : -c; });
  rows.forEach(r => body.appendChild(r));
}));
"""

_STYLE = """
body{font-family:sans-serif;margin:1em} table{border-collapse:collapse} th{cursor:pointer;background:#eee}
th,td{border:1px solid #ccc;padding:4px 8px;text-align:left;vertical-align:middle} img{width:160px}
tr.error td.status{background:#f6b0b0} tr.invalid td.status{background:#f6dca0} tr.ok td.status{background:#bfe6bf}
"""


def write_html(out: str, rows: list[BatchRow], *, title: str = "recon batch", previews: bool = True) -> None:
    """``summary.html``: the rows as a table sortable by any column (click its header), the failures first, a
    preview picture per converted part. Plain HTML and script: it opens offline."""
    fs, root = fs_of(out)
    order = {s: i for i, s in enumerate(STATUSES)}
    rows = sorted(rows, key=lambda r: (order.get(r.status, len(order)), r.input))
    counts = ", ".join(f"{sum(r.status == s for r in rows)} {s}" for s in STATUSES)
    head = "".join(f"<th>{c}</th>" for c in ["preview", *COLUMNS])
    body = []
    for r in rows:
        name = posixpath.basename(r.output)
        stem = posixpath.splitext(name)[0]
        picture = stem + PREVIEW_SUFFIX
        # On a local disk look; on a remote store (one request per part) trust the run's own flag.
        has_picture = bool(r.output) and (fs.exists(posixpath.join(root, picture)) if is_local(fs) else previews)
        img = f'<a href="{html.escape(picture)}"><img src="{html.escape(picture)}" alt=""></a>' if has_picture else ""
        out_cell = f'<a href="{html.escape(name)}">{html.escape(name)}</a>' if name else ""
        cells = [f'<td data-v="{int(has_picture)}">{img}</td>', f"<td>{html.escape(r.input)}</td>",
                 f'<td data-v="{html.escape(name)}">{out_cell}</td>',
                 f'<td class="status" data-v="{order.get(r.status, 9)}">{r.status}</td>']
        cells += [f"<td>{html.escape(_fmt(v))}</td>" for v in (r.faces, r.valid, r.mesh_to_shape_p95_pct, r.seconds)]
        cells.append(f"<td>{html.escape(r.message)}</td>")
        body.append(f'<tr class="{r.status}">{"".join(cells)}</tr>')
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1><p>{len(rows)} parts: {counts}. "
            f"Click a column's header to sort by it.</p><table><thead><tr>{head}</tr></thead><tbody>"
            + "\n".join(body) + f"</tbody></table><script>{_SCRIPT}</script></body></html>\n")
    path = posixpath.join(root, "summary.html")
    if is_local(fs):
        # Not recon's atomic_path, which refuses once the run is interrupted: the summary of what finished is what
        # an interrupted batch keeps. Written beside and renamed, a reader never sees half a page.
        tmp = posixpath.join(root, f".summary.html.{os.getpid()}")
        with open(tmp, "w") as fh:
            fh.write(page)
        os.replace(tmp, path)
    else:
        with fs.open(path, "w") as fh:
            fh.write(page)
