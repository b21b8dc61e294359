"""The polygon being drawn: vertices, closing, moving, deleting, undo/redo and grid snapping.

Plain Python (no Qt) so that it can be tested and reasoned about on its own.  Validity of a
closed polygon is judged by the core (:func:`quadmesh.polygon.validate_polygon`), so the live
warning says exactly what the mesher would say.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely

from quadmesh.errors import PolygonError
from quadmesh.polygon import validate_polygon

__all__ = ["PolygonEditor", "parse_coordinates"]


@dataclass
class _State:
    points: tuple[complex, ...]
    closed: bool


@dataclass
class PolygonEditor:
    """Editable polygon with an undo/redo history.

    Attributes:
        points: vertices in drawing order (complex).
        closed: True once the polygon has been closed.
        snap: round new and moved vertices to the grid.
        grid: grid spacing used by ``snap``.
    """

    points: list[complex] = field(default_factory=list)
    closed: bool = False
    snap: bool = False
    grid: float = 0.25
    _undo: list[_State] = field(default_factory=list, repr=False)
    _redo: list[_State] = field(default_factory=list, repr=False)
    _drag_start: _State | None = field(default=None, repr=False)

    # ------------------------------------------------------------------ history
    def _state(self) -> _State:
        return _State(tuple(self.points), self.closed)

    def _push(self) -> None:
        self._undo.append(self._state())
        self._redo.clear()

    def _restore(self, s: _State) -> None:
        self.points = list(s.points)
        self.closed = s.closed

    @property
    def can_undo(self) -> bool:
        """True when there is an edit to undo."""
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        """True when there is an undone edit to redo."""
        return bool(self._redo)

    def undo(self) -> bool:
        """Undo the last edit; return False when there was nothing to undo."""
        if not self._undo:
            return False
        self._redo.append(self._state())
        self._restore(self._undo.pop())
        return True

    def redo(self) -> bool:
        """Redo the last undone edit; return False when there was nothing to redo."""
        if not self._redo:
            return False
        self._undo.append(self._state())
        self._restore(self._redo.pop())
        return True

    # ------------------------------------------------------------------ edits
    def snapped(self, z: complex) -> complex:
        """``z`` rounded to the grid when snapping is on."""
        if not self.snap or self.grid <= 0:
            return complex(z)
        g = self.grid
        return complex(round(z.real / g) * g, round(z.imag / g) * g)

    def add(self, z: complex) -> bool:
        """Append a vertex (snapped); ignored when closed or equal to the last vertex."""
        if self.closed:
            return False
        z = self.snapped(z)
        if self.points and abs(self.points[-1] - z) == 0:
            return False
        self._push()
        self.points.append(z)
        return True

    def close(self) -> bool:
        """Close the polygon (needs at least 3 vertices)."""
        if self.closed or len(self.points) < 3:
            return False
        self._push()
        self.closed = True
        return True

    def begin_move(self) -> None:
        """Start dragging: the whole drag becomes one undo step."""
        self._drag_start = self._state()

    def move(self, i: int, z: complex) -> None:
        """Move vertex ``i`` to ``z`` (snapped).  Outside a drag it is its own undo step."""
        if self._drag_start is None:
            self._push()
        self.points[i] = self.snapped(z)

    def end_move(self) -> None:
        """Finish a drag; record it in the history if something changed."""
        if self._drag_start is not None and self._drag_start != self._state():
            self._undo.append(self._drag_start)
            self._redo.clear()
        self._drag_start = None

    def delete(self, i: int) -> bool:
        """Delete vertex ``i``; a closed polygon left with < 3 vertices becomes open."""
        if not 0 <= i < len(self.points):
            return False
        self._push()
        del self.points[i]
        if len(self.points) < 3:
            self.closed = False
        return True

    def clear(self) -> None:
        """Remove every vertex (undoable)."""
        if not self.points and not self.closed:
            return
        self._push()
        self.points = []
        self.closed = False

    def set_polygon(self, z: np.ndarray, closed: bool = True) -> None:
        """Replace the drawing by the given vertices (undoable)."""
        self._push()
        self.points = [complex(v) for v in np.asarray(z, dtype=np.complex128).ravel()]
        self.closed = closed and len(self.points) >= 3

    # ------------------------------------------------------------------ queries
    @property
    def z(self) -> np.ndarray:
        """The vertices as a complex array."""
        return np.asarray(self.points, dtype=np.complex128)

    def nearest(self, z: complex, tol: float) -> int | None:
        """Index of the vertex nearest to ``z`` if it is within ``tol``, else None."""
        if not self.points:
            return None
        d = np.abs(self.z - z)
        i = int(np.argmin(d))
        return i if d[i] <= tol else None

    def problem(self) -> str | None:
        """Why the drawing is not a valid simple polygon (None when it is, or may still become
        one).  A closed drawing is checked by :func:`validate_polygon`; an open one only for
        self-intersections of its polyline."""
        n = len(self.points)
        if self.closed:
            try:
                validate_polygon(self.z)
            except PolygonError as exc:
                return str(exc)
            return None
        if n >= 3:
            xy = np.column_stack([self.z.real, self.z.imag])
            if not shapely.LineString(xy).is_simple:
                return "the drawn outline crosses itself"
        return None


def parse_coordinates(text: str) -> np.ndarray:
    """The vertices typed or pasted as text, as a complex array.

    Accepted: one vertex per line as ``x y``, ``x, y`` or ``x; y`` (blank lines and lines
    starting with ``#`` are skipped), or a JSON list of ``[x, y]`` pairs (also under a
    ``"vertices"`` key of a JSON object).  A repeated first vertex at the end is dropped.

    Raises:
        ValueError: naming the line (1-based) or the JSON item that is no pair of numbers,
            or when fewer than three vertices are given.
    """
    import json

    s = text.strip()
    pts: list[complex] = []
    if s.startswith(("[", "{")):
        try:
            data = json.loads(s)
        except json.JSONDecodeError as exc:
            raise ValueError(
                f"the text looks like JSON but is not: {exc.msg} "
                f"(line {exc.lineno}, column {exc.colno})"
            ) from None
        if isinstance(data, dict):
            data = data.get("vertices")
        if not isinstance(data, list):
            raise ValueError('JSON must be a list of [x, y] pairs or {"vertices": [...]}')
        for k, item in enumerate(data):
            if (
                not isinstance(item, list | tuple)
                or len(item) != 2
                or not all(isinstance(c, int | float) and not isinstance(c, bool) for c in item)
            ):
                raise ValueError(f"JSON item {k} ({item!r}) is not a pair of numbers [x, y]")
            pts.append(complex(float(item[0]), float(item[1])))
    else:
        for lineno, line in enumerate(text.splitlines(), start=1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            fields = [f for f in line.replace(",", " ").replace(";", " ").split() if f]
            try:
                if len(fields) != 2:
                    raise ValueError
                x, y = float(fields[0]), float(fields[1])
            except ValueError:
                raise ValueError(
                    f"line {lineno} ({line!r}) is not two numbers 'x y' or 'x, y'"
                ) from None
            if not (np.isfinite(x) and np.isfinite(y)):
                raise ValueError(f"line {lineno} ({line!r}) has a coordinate that is not finite")
            pts.append(complex(x, y))
    if len(pts) > 3 and pts[0] == pts[-1]:
        pts.pop()
    if len(pts) < 3:
        raise ValueError(f"a polygon needs at least 3 vertices; the text gives {len(pts)}")
    return np.asarray(pts, dtype=np.complex128)
