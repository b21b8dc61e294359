"""The two 2-D views (plane and unit disk): pyvistaqt interactors that hold layers.

A view owns, per layer, the :class:`quadmesh.render.LayerGeometry` it draws, the actors made
by :func:`quadmesh.render.add_layer` and the layer's visibility, colour and opacity.  Hiding a
layer hides its colour bar too.  Left-button events are taken away from VTK by a Qt event
filter and handed to the view's owner (drawing in the plane, the teaching tool in the disk);
the middle button pans and the wheel zooms.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from PySide6.QtCore import QEvent, QObject, Qt, QTimer, Signal
from PySide6.QtWidgets import QWidget
from pyvistaqt import QtInteractor

from quadmesh.hyperbolic.isometry import Isometry
from quadmesh.render import LayerGeometry, LayerPart, add_layer, fit_camera

__all__ = [
    "LOD_CELLS",
    "LOD_SUBPIXEL",
    "LayerState",
    "View2D",
    "cell_widths",
    "fine_split",
    "light_stand_in",
]

#: parts with more cells than this are drawn lighter while the user interacts (a drag, a zoom
#: step, a layer toggle): surfaces by a vertex-clustered copy, wireframes not at all
LOD_CELLS = 200_000
#: grid of the vertex clustering that makes a heavy surface's stand-in (per axis)
LOD_DIVISIONS = 256
#: idle time after a zoom step or a toggle before the full-detail frame is drawn
LOD_SETTLE_MS = 250
#: grid (per axis, over a heavy part's bounding box) of the vertex clustering that stands in,
#: in settled frames, for the cells narrower than half a grid step (see :func:`fine_split`)
LOD_FINE_DIVISIONS = 512
#: settled frames use that split while one grid step is at most this many screen pixels (so
#: every cell it replaces is under one pixel wide); zoomed in further they draw the true parts
LOD_SUBPIXEL = 2.0


def cell_widths(part: LayerPart) -> np.ndarray:
    """Width of each cell of ``part`` in world units: the square root of the area of a 2-D
    cell, the length of a line."""
    sizes = part.mesh.compute_cell_sizes(length=True, area=True, volume=False)
    area = np.asarray(sizes.cell_data["Area"])
    length = np.asarray(sizes.cell_data["Length"])
    return np.where(area > 0, np.sqrt(np.abs(area)), length)


def _subset(part: LayerPart, keep: np.ndarray, label: str) -> LayerPart:
    """The cells ``keep`` (a boolean mask) of ``part`` as a part of their own (no colour bar;
    disk parts keep the disk coordinates of the points they use)."""
    sub = part.mesh.remove_cells(np.flatnonzero(~keep), pass_point_ids=True)
    ids = np.asarray(sub.point_data["vtkOriginalPointIds"])
    del sub.point_data["vtkOriginalPointIds"]
    return replace(
        part,
        mesh=sub,
        scalar_bar_title=None,
        label=label,
        disk_z=None if part.disk_z is None else part.disk_z[ids],
    )


def _cluster(
    part: LayerPart, mesh: Any, divisions: int, label: str, inverse: Isometry | None = None
) -> LayerPart:
    """Vertex clustering of ``mesh`` (cells of ``part``) on a ``divisions``² grid over its
    bounding box; each output triangle keeps the colour value of one of the input cells it
    covers (point colour values are first averaged per cell).  Disk parts: ``inverse`` undoes
    the automorphism ``mesh`` is moved by (None: it is not moved)."""
    from vtkmodules.vtkFiltersCore import vtkQuadricClustering

    if part.scalars is not None and part.scalars in mesh.point_data.keys():
        mesh = mesh.point_data_to_cell_data()
    f = vtkQuadricClustering()
    f.SetInputData(mesh)
    f.AutoAdjustNumberOfDivisionsOff()
    f.SetNumberOfDivisions(divisions, divisions, 1)
    f.CopyCellDataOn()
    f.Update()
    import pyvista as pv

    light = pv.wrap(f.GetOutput())
    disk_z = None
    if part.disk_z is not None:
        pts = np.asarray(light.points)
        disk_z = (pts[:, 0] + 1j * pts[:, 1]) / part.disk_scale
        if inverse is not None:
            disk_z = np.asarray(inverse(disk_z))
    return LayerPart(
        light,
        color=part.color,
        opacity=part.opacity,
        scalars=part.scalars,
        cmap=part.cmap,
        clim=part.clim,
        label=label,
        disk_z=disk_z,
        disk_scale=part.disk_scale,
    )


def fine_split(
    parts: list[LayerPart], inverse: Isometry | None = None
) -> tuple[float, list[LayerPart]] | None:
    """What a settled frame draws for the heavy ``parts`` of a layer while their finest cells
    are below pixel size: (grid step, parts), or None when a heavy part is made of points or
    no cell is narrower than half a grid step.

    The grid step is the largest extent of a heavy surface's bounding box (of a heavy part's
    when the layer has only lines) divided by :data:`LOD_FINE_DIVISIONS`.  Every cell at
    least half a step wide (the large cells of a graded mesh, with their edges) is kept as it
    is; the narrower cells of each surface are replaced by their vertex clustering on that
    grid, and narrower wireframe cells (edges) are left out.  Disk parts moved by an
    automorphism are split as they are on screen (``inverse``: its inverse, for the disk
    coordinates of the clustering).
    """
    surfaces = [p for p in parts if p.style == "surface"] or parts
    if not parts or any(p.style == "points" for p in parts):
        return None
    step = (
        max(max(b[1] - b[0], b[3] - b[2]) for b in (p.mesh.bounds for p in surfaces))
        / LOD_FINE_DIVISIONS
    )
    bigs = [cell_widths(p) >= 0.5 * step for p in parts]
    if all(big.all() for big in bigs):
        return None  # no cell is that small: nothing to save
    out = []
    for p, big in zip(parts, bigs, strict=True):
        if big.any():
            out.append(_subset(p, big, f"{p.label} (large cells)"))
        if p.style == "surface" and not big.all():
            fine = p.mesh.remove_cells(np.flatnonzero(big)) if big.any() else p.mesh
            label = f"{p.label} (sub-pixel cells)"
            out.append(_cluster(p, fine, LOD_FINE_DIVISIONS, label, inverse))
    return step, out


def light_stand_in(part: LayerPart) -> LayerPart | None:
    """A light copy of a heavy part for interaction-time drawing, or None when the part is not
    heavy (at most :data:`LOD_CELLS` cells) or is a wireframe/points part (hidden while the
    user interacts).

    The stand-in of a surface is its vertex clustering on a ``LOD_DIVISIONS``² grid over its
    bounding box (each output triangle keeps the colour value of one of the input cells it
    covers; point colour values are first averaged per cell), so it has at most about
    2·``LOD_DIVISIONS``² triangles.  Disk parts get the stand-in's own disk coordinates, so a
    disk automorphism moves it like the part.  Build it while the part is untransformed.
    """
    if part.n_cells <= LOD_CELLS or part.style != "surface":
        return None
    return _cluster(part, part.mesh, LOD_DIVISIONS, f"{part.label} (light)")


@dataclass
class LayerState:
    """What a view knows about one layer."""

    geometry: LayerGeometry | None = None
    actors: list[Any] = field(default_factory=list)
    #: per drawn part: True if it is heavy (more than LOD_CELLS cells)
    heavy: list[bool] = field(default_factory=list)
    #: stand-in parts and their actors, drawn instead of heavy surfaces while interacting
    light_parts: list[LayerPart] = field(default_factory=list)
    light_actors: list[Any] = field(default_factory=list)
    #: settled frames with sub-pixel cells draw these instead of the heavy parts (see
    #: :func:`fine_split`; fine_step is its grid step, 0 when the layer has no split)
    fine_parts: list[LayerPart] = field(default_factory=list)
    fine_actors: list[Any] = field(default_factory=list)
    fine_step: float = 0.0
    #: the disk automorphism the split of disk parts was made for (None: the identity)
    fine_key: Any = None
    #: the layer has a split and disk parts (remade for each automorphism)
    fine_disk: bool = False
    visible: bool = True
    #: labels of parts kept hidden while the layer is shown (the polygon's fill while a mesh is
    #: on screen); every redraw of the layer's visibility honours it
    hidden: frozenset[str] = frozenset()
    color: str | None = None
    opacity: float | None = None


class _MouseFilter(QObject):
    """Forwards left-button mouse events of the interactor to the view (and eats them); eats
    key events so that VTK's single-key shortcuts cannot change the views."""

    def __init__(self, view: View2D) -> None:
        super().__init__(view.plotter)
        self._view = view
        self._press_at: tuple[float, float] | None = None

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:
        et = event.type()
        v = self._view
        if et == QEvent.Wheel:
            # zoom about the cursor: the world point under it stays under it
            steps = event.angleDelta().y() / 120.0
            if steps:
                pos = event.position()
                v.zoom_at(pos.x(), pos.y(), 1.2**steps)
            return True
        if et == QEvent.MouseButtonPress:
            v._mouse_down = True
            v.begin_interaction()  # pans and disk drags are drawn light until the release
        elif et == QEvent.MouseButtonRelease:
            v._mouse_down = False
            handled = self._dispatch(obj, event)
            if handled:
                v.end_interaction()
            else:  # VTK ends its pan with one more (light) frame: full detail after it
                QTimer.singleShot(0, v, v.end_interaction)  # dropped if v is gone
            return handled
        return self._dispatch(obj, event)

    def _dispatch(self, obj: QObject, event: QEvent) -> bool:
        et = event.type()
        v = self._view
        if et in (QEvent.KeyPress, QEvent.KeyRelease):
            # VTK's keyboard shortcuts (w: wireframe, j: joystick, q/e: quit, 3: stereo, ...)
            # would break the 2-D views; the window's own shortcuts are QActions and still work
            return True
        if et == QEvent.Wheel or (
            et == QEvent.MouseButtonPress
            and (event.button() != Qt.LeftButton or not v.capture_left)
        ):
            v.fit_bounds = None  # the user takes over the camera
        if not v.capture_left:
            # the left button pans; a press and release within a few pixels is a click
            # (picking a quad), reported after VTK has seen both events
            if et == QEvent.MouseMove:
                v.mouse.emit("hover", v.to_world(event.position().x(), event.position().y()), 0)
            elif et == QEvent.MouseButtonPress and event.button() == Qt.LeftButton:
                self._press_at = (event.position().x(), event.position().y())
            elif et == QEvent.MouseButtonRelease and event.button() == Qt.LeftButton:
                x, y = event.position().x(), event.position().y()
                start, self._press_at = self._press_at, None
                if start is not None and abs(x - start[0]) + abs(y - start[1]) <= 4:
                    v.mouse.emit("click", v.to_world(x, y), event.modifiers().value)
            return False
        if et in (QEvent.MouseButtonPress, QEvent.MouseButtonDblClick):
            if event.button() != Qt.LeftButton:
                return False
            x, y = event.position().x(), event.position().y()
            v.mouse.emit(
                "dblclick" if et == QEvent.MouseButtonDblClick else "press",
                v.to_world(x, y),
                event.modifiers().value,
            )
            return True
        if et == QEvent.MouseMove and event.buttons() & Qt.LeftButton:
            v.mouse.emit("drag", v.to_world(event.position().x(), event.position().y()), 0)
            return True
        if et == QEvent.MouseMove:
            v.mouse.emit("hover", v.to_world(event.position().x(), event.position().y()), 0)
            return False
        if et == QEvent.MouseButtonRelease and event.button() == Qt.LeftButton:
            v.mouse.emit("release", v.to_world(event.position().x(), event.position().y()), 0)
            return True
        return False


class View2D(QWidget):
    """A parallel-projection xy view with named layers.

    Signals:
        mouse(kind, world_point, modifiers): kind in {"press", "dblclick", "drag", "release",
            "hover", "click"}; world_point is complex.  While the left button is captured it
            gives press/dblclick/drag/release/hover; otherwise (the left button pans) "hover"
            for every move and "click" for a press and release less than 5 pixels apart.
    """

    mouse = Signal(str, complex, int)

    def __init__(self, view: str, parent: QWidget | None = None, *, auto_update: bool = False):
        super().__init__(parent)
        from PySide6.QtWidgets import QVBoxLayout

        self.view = view
        self.plotter = QtInteractor(self, auto_update=auto_update)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.plotter)
        self.plotter.set_background("white")
        self.plotter.enable_parallel_projection()
        self.plotter.enable_custom_trackball_style(
            left="pan",
            shift_left="pan",
            control_left="pan",
            middle="pan",
            shift_middle="pan",
            control_middle="pan",
            right="dolly",
            shift_right="dolly",
            control_right="dolly",
        )
        self.plotter.view_xy()
        self.layers: dict[str, LayerState] = {}
        self.overlays: dict[str, list[Any]] = {}
        self.capture_left = False
        self.transform: Isometry | None = None
        self.fit_bounds: tuple[float, float, float, float] | None = None
        self._parked: dict[str, tuple[LayerGeometry, LayerState]] = {}
        self.interacting = False
        self._mouse_down = False
        self._settle = QTimer(self)
        self._settle.setSingleShot(True)
        self._settle.timeout.connect(self.end_interaction)
        self._stale = False  # heavy disk parts lag behind the transform
        self._light_drawn = False  # a light frame was drawn since begin_interaction
        self._samples = 0  # multisamples of the full-detail frames (kept while light)
        self.full_detail = False  # True: settled frames draw the true geometry (screenshots)
        self.plotter.renderer.AddObserver("StartEvent", self._on_render_start)
        # the window's StartEvent comes before its renderers gather their visible props
        self.plotter.ren_win.AddObserver("StartEvent", self._update_detail)
        self._filter = _MouseFilter(self)
        self.plotter.installEventFilter(self._filter)

    # ------------------------------------------------------------------ coordinates
    def to_world(self, x: float, y: float) -> complex:
        """World (z = 0 plane) point under widget pixel (x, y) (Qt logical pixels)."""
        ren = self.plotter.renderer
        dpr = self.plotter.devicePixelRatioF()
        h = self.plotter.height()
        ren.SetDisplayPoint(x * dpr, (h - y) * dpr, 0.0)
        ren.DisplayToWorld()
        wx, wy, _, w = ren.GetWorldPoint()
        if w:
            wx, wy = wx / w, wy / w
        return complex(wx, wy)

    def to_widget(self, z: complex) -> tuple[float, float]:
        """Widget pixel (logical) of world point ``z``."""
        ren = self.plotter.renderer
        dpr = self.plotter.devicePixelRatioF()
        h = self.plotter.height()
        ren.SetWorldPoint(z.real, z.imag, 0.0, 1.0)
        ren.WorldToDisplay()
        dx, dy, _ = ren.GetDisplayPoint()
        return dx / dpr, h - dy / dpr

    def pixel_size(self) -> float:
        """World length of one widget pixel (parallel projection)."""
        cam = self.plotter.camera
        return 2.0 * cam.parallel_scale / max(self.plotter.height(), 1)

    # ------------------------------------------------------------------ layers
    def set_layer(self, name: str, geometry: LayerGeometry | None, *, park: bool = False) -> None:
        """Replace the geometry of layer ``name`` (None removes it), keeping its settings.

        ``park``: keep the replaced geometry's actors (hidden) so that setting it again only
        swaps actors (switching a layer between two colourings); a layer keeps one parked
        geometry, and a later call without ``park`` drops it.
        """
        st = self.layers.setdefault(name, LayerState())
        parked = self._parked.pop(name, None)
        if park and st.geometry is not None and parked is not None and parked[0] is geometry:
            self._parked[name] = (st.geometry, self._detach(st))
            self._attach(st, geometry, parked[1])
            return
        if parked is not None:
            self._remove_actors(parked[1])
        if park and st.geometry is not None and st.geometry is not geometry:
            self._parked[name] = (st.geometry, self._detach(st))
        else:
            self._remove_actors(self._detach(st))
        st.geometry = geometry
        if geometry is None:
            return
        drawn = self._drawn_parts(st)
        light = [light_stand_in(p) for p in drawn]
        st.heavy = [p.n_cells > LOD_CELLS for p in drawn]
        st.light_parts = [p for p in light if p is not None]
        split = fine_split([p for p, h in zip(drawn, st.heavy, strict=True) if h])
        st.fine_step, st.fine_parts = split if split is not None else (0.0, [])
        st.fine_key = None
        st.fine_disk = any(p.disk_z is not None for p in st.fine_parts)
        st.actors = add_layer(self.plotter, geometry, visible=False)
        st.light_actors = add_layer(
            self.plotter, LayerGeometry(name, geometry.view, st.light_parts), visible=False
        )
        st.fine_actors = add_layer(
            self.plotter, LayerGeometry(name, geometry.view, st.fine_parts), visible=False
        )
        self._apply_style(st)
        if self.transform is not None:
            self._transform_state(st)
            self._resplit(st)
        self._show(st)

    def _detach(self, st: LayerState) -> LayerState:
        """Hide the actors of ``st`` and move them (with its geometry) to a new state."""
        old = LayerState(
            st.geometry,
            st.actors,
            st.heavy,
            st.light_parts,
            st.light_actors,
            st.fine_parts,
            st.fine_actors,
            st.fine_step,
            st.fine_key,
            st.fine_disk,
        )
        for a in old.actors + old.light_actors + old.fine_actors:
            a.SetVisibility(False)
        for bar in self._bars(old):
            bar.SetVisibility(False)
        st.geometry, st.actors, st.heavy, st.light_parts, st.light_actors = None, [], [], [], []
        st.fine_parts, st.fine_actors, st.fine_step, st.fine_key = [], [], 0.0, None
        st.fine_disk = False
        return old

    def _attach(self, st: LayerState, geometry: LayerGeometry, old: LayerState) -> None:
        st.geometry, st.actors, st.heavy = geometry, old.actors, old.heavy
        st.light_parts, st.light_actors = old.light_parts, old.light_actors
        st.fine_parts, st.fine_actors, st.fine_step = old.fine_parts, old.fine_actors, old.fine_step
        st.fine_key, st.fine_disk = old.fine_key, old.fine_disk
        self._apply_style(st)
        if self.transform is not None or self._stale:
            self._transform_state(st)
            if not self.interacting:
                self._resplit(st)
        self._show(st)

    def _bars(self, st: LayerState) -> list[Any]:
        if st.geometry is None:
            return []
        bars = self.plotter.scalar_bars
        return [bars[t] for t in st.geometry.scalar_bar_titles if t in bars.keys()]

    def _remove_actors(self, st: LayerState) -> None:
        for a in st.actors + st.light_actors + st.fine_actors:
            self.plotter.remove_actor(a, render=False)
        if st.geometry is not None:
            for title in st.geometry.scalar_bar_titles:
                if title in self.plotter.scalar_bars.keys():
                    self.plotter.remove_scalar_bar(title, render=False)
        st.actors, st.light_actors, st.fine_actors = [], [], []

    def clear_layers(self, names: list[str] | None = None) -> None:
        """Remove the geometry of the given layers (all when None)."""
        for name in list(self.layers) if names is None else names:
            if name in self.layers:
                self.set_layer(name, None)

    def set_visible(self, name: str, visible: bool) -> None:
        """Show or hide a layer together with its colour bars."""
        st = self.layers.setdefault(name, LayerState())
        st.visible = visible
        self._show(st)

    def _show(self, st: LayerState) -> None:
        """Visibility of the actors of ``st``: heavy parts give way to their light stand-ins
        (or to nothing) while the user interacts, and in the settled frame too while their
        cells are below pixel size (see :meth:`subpixel`)."""
        light = self.interacting
        fine = not light and self.subpixel(st)
        labels = [p.label for p in self._drawn_parts(st)] if st.hidden else None
        for k, (a, heavy) in enumerate(zip(st.actors, st.heavy, strict=True)):
            shown = st.visible and (labels is None or labels[k] not in st.hidden)
            a.SetVisibility(shown and not ((light or fine) and heavy))
        for a in st.light_actors:
            a.SetVisibility(st.visible and light)
        for a in st.fine_actors:
            a.SetVisibility(st.visible and fine)
        for bar in self._bars(st):
            bar.SetVisibility(st.visible)

    def show_layer_parts(self, name: str) -> None:
        """Apply layer ``name``'s visibility, its hidden parts (:attr:`LayerState.hidden`)
        included, to its actors now (drawn at the next render)."""
        st = self.layers.get(name)
        if st is not None and st.geometry is not None and len(st.actors) == len(st.heavy):
            self._show(st)

    # ------------------------------------------------------------------ settled detail
    def device_pixel_size(self) -> float:
        """World length of one device pixel of the render window (parallel projection)."""
        h = self.plotter.ren_win.GetSize()[1]
        return 2.0 * self.plotter.camera.parallel_scale / max(h, 1)

    def subpixel(self, st: LayerState) -> bool:
        """Whether the settled frame draws layer ``st`` by its :func:`fine_split` (the cells
        narrower than half a grid step by their clustering, the larger ones as they are): while
        one grid step is at most :data:`LOD_SUBPIXEL` device pixels.  Never while
        :attr:`full_detail` is set (screenshots), nor for disk parts whose split was made for
        another automorphism (remade once the user lets go, see :meth:`_resplit`)."""
        if self.full_detail or not st.fine_parts:
            return False
        if st.fine_disk and st.fine_key is not self.transform:
            return False  # made for another automorphism (until the next _resplit)
        return st.fine_step <= LOD_SUBPIXEL * self.device_pixel_size()

    def _update_detail(self, *_: Any) -> None:
        """Before each frame of the render window: settled frames follow the camera (light
        stand-ins while the heavy cells are sub-pixel, true geometry once they are not)."""
        if not self.interacting:
            for st in self.layers.values():
                if len(st.actors) == len(st.heavy):  # not while set_layer adds actors
                    self._show(st)

    def set_full_detail(self, on: bool) -> None:
        """Draw every settled frame with the true geometry, sub-pixel or not (screenshots)."""
        self.full_detail = on
        self._update_detail()

    # ------------------------------------------------------------------ interaction detail
    def begin_interaction(self) -> None:
        """Draw heavy parts light (see :func:`light_stand_in`) and every frame without
        multisampling until :meth:`end_interaction`."""
        self._settle.stop()
        if self.interacting:
            return
        self.interacting = True
        # with Mesa's software OpenGL 4x MSAA costs more than most geometry (an empty 370x820
        # view: 21 ms with it, 0.5 ms without): frames while the user acts go without it, on
        # small meshes too; the full-detail frame after the interaction has it again
        rw = self.plotter.ren_win
        self._samples = rw.GetMultiSamples()
        rw.SetMultiSamples(0)
        for st in self.layers.values():
            self._show(st)

    def end_interaction(self, render: bool = True) -> None:
        """Back to full detail (the heavy parts catch up with the disk transform); redraw if
        a light frame was shown."""
        self._settle.stop()
        if not self.interacting:
            return
        self.interacting = False
        self.plotter.ren_win.SetMultiSamples(self._samples)
        for st in self.layers.values():
            if self._stale:
                self._transform_state(st)
            self._resplit(st)
            self._show(st)
        self._stale = False
        if render and self._light_drawn:
            self.plotter.render()
        self._light_drawn = False

    def _on_render_start(self, *_: Any) -> None:
        if self.interacting:
            self._light_drawn = True

    def interact_briefly(self) -> None:
        """Light drawing now and full detail after ``LOD_SETTLE_MS`` without another call (a
        zoom step, a layer toggle, a colour switch)."""
        if self._mouse_down:
            return
        self.begin_interaction()
        if self.interacting:
            self._settle.start(LOD_SETTLE_MS)

    def has_heavy_parts(self) -> bool:
        """Whether a visible layer has a part with more than ``LOD_CELLS`` cells."""
        return any(st.visible and any(st.heavy) for st in self.layers.values())

    def set_color(self, name: str, color: str) -> None:
        """Colour of the flat-coloured parts of a layer."""
        st = self.layers.setdefault(name, LayerState())
        st.color = color
        self._apply_style(st)

    def set_opacity(self, name: str, opacity: float) -> None:
        """Opacity (0..1) of every part of a layer."""
        st = self.layers.setdefault(name, LayerState())
        st.opacity = opacity
        self._apply_style(st)

    def _apply_style(self, st: LayerState) -> None:
        if st.geometry is None:
            return
        pairs = list(zip(self._drawn_parts(st), st.actors, strict=True))
        pairs += list(zip(st.light_parts, st.light_actors, strict=True))
        pairs += list(zip(st.fine_parts, st.fine_actors, strict=True))
        for part, actor in pairs:
            if st.color is not None and part.scalars is None and part.style != "points":
                actor.prop.color = st.color
            if st.opacity is not None:
                actor.prop.opacity = st.opacity * part.opacity

    @staticmethod
    def _drawn_parts(st: LayerState) -> list:
        return [p for p in st.geometry.parts if p.mesh.n_points > 0] if st.geometry else []

    def layer_actors(self, name: str) -> list[Any]:
        """Actors currently drawing layer ``name``."""
        st = self.layers.get(name)
        return list(st.actors) if st else []

    # ------------------------------------------------------------------ overlays
    def set_overlay(self, key: str, geometry: LayerGeometry | None) -> None:
        """Helper geometry that is not a layer (drawing handles, picked points, ...)."""
        for a in self.overlays.pop(key, []):
            self.plotter.remove_actor(a, render=False)
        if geometry is not None:
            self.overlays[key] = add_layer(self.plotter, geometry)

    # ------------------------------------------------------------------ disk automorphisms
    def set_transform(self, g: Isometry | None) -> None:
        """Move every disk-coordinate part by the isometry ``g`` (None = identity)."""
        self.transform = g
        self._stale = self._stale or self.interacting
        for st in self.layers.values():
            self._transform_state(st)
            if not self.interacting:
                self._resplit(st)

    def _resplit(self, st: LayerState) -> None:
        """Remake the :func:`fine_split` of a layer's disk parts for the automorphism they are
        moved by now (it changes which cells are small); call once they have been moved."""
        if st.geometry is None or not st.fine_disk or st.fine_key is self.transform:
            return
        heavy = [p for p, h in zip(self._drawn_parts(st), st.heavy, strict=True) if h]
        inverse = None if self.transform is None else self.transform.inverse()
        split = fine_split(heavy, inverse)
        step, parts = split if split is not None else (0.0, [])
        st.fine_key = self.transform
        if [p.label for p in parts] == [p.label for p in st.fine_parts]:
            # the same actors draw the new split: they keep their place in the drawing order
            for actor, part in zip(st.fine_actors, parts, strict=True):
                actor.mapper.SetInputData(part.mesh)
            st.fine_step, st.fine_parts = step, parts
            return
        for a in st.fine_actors:
            self.plotter.remove_actor(a, render=False)
        st.fine_step, st.fine_parts = step, parts
        st.fine_actors = add_layer(
            self.plotter,
            LayerGeometry(st.geometry.name, st.geometry.view, st.fine_parts),
            visible=False,
        )
        self._apply_style(st)

    def _transform_state(self, st: LayerState) -> None:
        """Move the disk parts of ``st``; while the user interacts, only the drawn ones (the
        heavy parts catch up in :meth:`end_interaction`)."""
        parts = self._drawn_parts(st)
        if self.interacting:
            parts = [p for p, heavy in zip(parts, st.heavy, strict=True) if not heavy]
        for part in parts + st.light_parts + st.fine_parts:
            if part.disk_z is None:
                continue
            w = part.disk_z if self.transform is None else self.transform(part.disk_z)
            w = w * part.disk_scale
            pts = np.asarray(part.mesh.points)
            pts[:, 0] = w.real
            pts[:, 1] = w.imag
            part.mesh.points = pts

    # ------------------------------------------------------------------ camera
    def reset_view(
        self, bounds: tuple[float, float, float, float] | None = None, *, keep: bool = False
    ) -> None:
        """Fit the camera to ``bounds`` (xmin, xmax, ymin, ymax), whatever the widget's aspect
        ratio, or to everything drawn.  ``keep``: refit to these bounds on every resize."""
        self.fit_bounds = bounds if keep else None
        if bounds is None:
            self.plotter.view_xy()
            self.plotter.reset_camera()
            self.plotter.render()
            return
        aspect = max(self.plotter.width(), 1) / max(self.plotter.height(), 1)
        fit_camera(self.plotter, bounds, aspect)
        self.plotter.render()

    def resizeEvent(self, event: object) -> None:  # Qt API
        super().resizeEvent(event)
        if self.fit_bounds is not None:
            self.reset_view(self.fit_bounds)

    def zoom(self, factor: float) -> None:
        """One zoom step by ``factor`` (> 1 zooms in), drawn light on heavy layers."""
        self.fit_bounds = None
        self.interact_briefly()
        self.plotter.camera.zoom(factor)
        self.plotter.render()

    def zoom_at(self, x: float, y: float, factor: float) -> None:
        """Zoom by ``factor`` (> 1 zooms in) about widget pixel (x, y): the world point under
        that pixel stays under it (the wheel does this)."""
        before = self.to_world(x, y)
        self.fit_bounds = None
        self.interact_briefly()
        cam = self.plotter.camera
        cam.zoom(factor)
        after = self.to_world(x, y)
        d = before - after
        fx, fy, fz = cam.focal_point
        px, py, pz = cam.position
        cam.focal_point = (fx + d.real, fy + d.imag, fz)
        cam.position = (px + d.real, py + d.imag, pz)
        self.plotter.render()

    def render(self) -> None:
        """Redraw now."""
        self.plotter.render()

    def close_plotter(self) -> None:
        """Release the VTK render window (call before the widget is destroyed)."""
        self.plotter.removeEventFilter(self._filter)
        self.plotter.close()
