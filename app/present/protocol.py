"""One protocol for every result: ``to_dict``, ``to_json``, ``summary``, ``save``, ``_repr_html_``.

Each result type (calibration, diagnosis, simulation, plan, export, cloud, validation) writes
its own ``to_dict`` (the command's ``--json`` object) and, where it has one, its own
``summary`` (the command's text report); this mixin gives every one of them the rest, the same
way: strict JSON (:func:`handeye.app.common.jsonio.dumps`), an atomic save, and a compact table in
Jupyter made from the summary's ``name: value`` lines.
"""
from __future__ import annotations

import html

from handeye.app.common.jsonio import dumps


class ResultProtocol:
    """Mixin: ``to_json``, ``save``, a default ``summary`` and ``_repr_html_`` from ``to_dict``."""

    #: Caption of the Jupyter table.
    caption = "handeye result"

    def to_dict(self):  # pragma: no cover - every result type defines its own
        raise NotImplementedError

    def to_json(self, indent=1):
        """:meth:`to_dict` as strict JSON text (non-finite numbers as null)."""
        return dumps(self.to_dict(), indent)

    def save(self, path):
        """Write :meth:`to_json` atomically to ``path``."""
        from handeye.app.common.files import write_text_atomically

        write_text_atomically(path, self.to_json(), option="--out")

    def summary(self):
        """Text report: one ``name: value`` line per top-level scalar or short list of :meth:`to_dict`."""
        lines = []
        for key, value in self.to_dict().items():
            if isinstance(value, (str, int, float, bool)) or value is None:
                lines.append(f"{key}: {value}")
            elif isinstance(value, (list, tuple)) and len(value) <= 8 and all(not isinstance(v, (dict, list))
                                                                               for v in value):
                lines.append(f"{key}: {', '.join(str(v) for v in value) or 'none'}")
        return "\n".join(lines)

    def _html_rows(self):
        """The Jupyter table's ``(name, value)`` rows: the summary's ``name: value`` lines (a result
        type may give its own)."""
        split = [(line, *line.partition(": ")) for line in self.summary().splitlines() if line.strip()]
        return [(key.strip(), value) if sep and len(key) <= 60 else ("", line) for line, key, sep, value in split]

    def _repr_html_(self):
        body = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th><td style='text-align:left'>"
                       f"{html.escape(str(v))}</td></tr>" for k, v in self._html_rows())
        return f"<table><caption>{html.escape(self.caption)}</caption>{body}</table>"
