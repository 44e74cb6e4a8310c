"""The viser scene and GUI of a :class:`ViewModel` (https://viser.studio; its client is a static build
inside the wheel, so the page loads with no network).

:func:`start_viewer` returns at once with the server running in its own threads: the CLI waits for
Ctrl-C, a test drives it from a browser and stops it.
"""

from __future__ import annotations

import contextlib
import io
import socket
import threading
from dataclasses import dataclass, field

import numpy as np

from ._maps import (
    distance_image,
    irradiance_colours,
    normal_image,
    radiance_image,
    read_npz_row,
    tile,
)
from ._model import (
    COLOUR_STATUS,
    SIZE_UNIFORM,
    STATUS_LABELS,
    STATUS_RGB,
    UNCOVERED_RGB,
    ViewCamera,
    ViewModel,
)

#: the irradiance sphere: this many points, this many marker radii across (it hides the marker)
SPHERE_POINTS = 4000
SPHERE_RADII = 3.0
STRIP_GAP = 8
#: evaluation camera frustum colour; the other views are drawn dark grey
EVAL_RGB = (255, 140, 0)


def camera_wxyz(cam: ViewCamera) -> np.ndarray:
    """Quaternion (w, x, y, z) turning viser's camera frame (OpenCV: +x right, +y down, +z forward) into
    the world pose of ``cam``."""
    from viser import transforms

    forward = cam.look_at - cam.position
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, cam.up)
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return transforms.SO3.from_matrix(np.stack([right, down, forward], axis=1)).wxyz


def map_strip(*images: np.ndarray) -> np.ndarray:
    """Octahedral maps side by side, each resized to :data:`_maps.TILE_PX` a side, white gaps of
    :data:`STRIP_GAP` pixels: one GUI image, so the three read at a glance without scrolling."""
    tiles = [tile(img) for img in images]
    gap = np.full((tiles[0].shape[0], STRIP_GAP, 3), 255, np.uint8)
    return np.concatenate([x for t in tiles for x in (t, gap)][:-1], axis=1)


def pick_probe(positions: np.ndarray, radii: np.ndarray, origin, direction) -> int | None:
    """The probe whose marker sphere a click ray hits first, or None (the ray misses every marker)."""
    o, d = np.asarray(origin, np.float64), np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    rel = np.asarray(positions, np.float64) - o
    t_mid = rel @ d
    miss2 = np.sum(rel * rel, axis=1) - t_mid**2  # squared distance from the centre to the ray's line
    hit = (miss2 <= radii**2) & (t_mid > 0)
    if not hit.any():
        return None
    t_enter = t_mid - np.sqrt(np.maximum(radii**2 - miss2, 0.0))
    return int(np.flatnonzero(hit)[np.argmin(t_enter[hit])])


def split_by_colour(vertices: np.ndarray, faces: np.ndarray, face_rgb: np.ndarray):
    """The mesh as one sub-mesh per face colour (viser meshes have one colour each): yields
    (rgb, vertices, faces) with each sub-mesh's vertices re-indexed."""
    key = face_rgb.astype(np.int64) @ np.array([1 << 16, 1 << 8, 1])
    for k in np.unique(key):
        f = faces[key == k]
        used, local = np.unique(f, return_inverse=True)
        yield (
            tuple(int(c) for c in face_rgb[key == k][0]),
            vertices[used],
            local.reshape(f.shape).astype(np.int32),
        )


def view_url(host: str, port: int) -> str:
    """The address a person opens: ``localhost`` for a loopback or wildcard bind (the SSH forward's end),
    else the host given."""
    shown = "localhost" if host in ("127.0.0.1", "localhost", "::1", "0.0.0.0", "::", "") else host
    return f"http://{shown}:{port}"


@dataclass
class Viewer:
    """A running viewer. ``select(i)`` is what a click on probe ``i`` does (also callable from code)."""

    server: object
    model: ViewModel
    url: str
    selected: int | None = None
    _gui: dict = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def stop(self) -> None:
        with contextlib.redirect_stdout(io.StringIO()):  # viser's "Server stopped" line
            self.server.stop()

    # --- probes -------------------------------------------------------------------------------------
    def radii(self) -> np.ndarray:
        return self.model.radii(self._gui["size"].value)

    def restyle(self) -> None:
        h = self._gui["probes"]
        if h is None:
            return
        by = self._gui["colour"].value
        h.batched_colors = self.model.colours(by)
        self._gui["colour_legend"].content = self.model.legend(by)
        scales = self.radii().astype(np.float32)
        if self.selected is not None and self.model.baked is not None:
            # its irradiance ball stands in for it (viser's points do not hide what is inside them)
            scales[self.selected] = 0.0
        h.batched_scales = scales

    def select(self, i: int | None) -> None:
        """Show probe ``i``'s panel (position, status, maps) and its irradiance sphere; None clears."""
        m, g = self.model, self._gui
        with self._lock:
            self.selected = i
            self.restyle()
            if i is None:
                g["selected"].content = "Click a probe to see its maps."
                self.server.scene.remove_by_name("/selected")
                g["maps"].visible = False
                return
            p = m.positions[i]
            lines = [
                f"**probe {i}** at ({p[0]:.4g}, {p[1]:.4g}, {p[2]:.4g}): {STATUS_LABELS[m.status[i]]}",
                *probe_figures(m, i),
            ]
            b = m.baked
            if b is None:
                g["selected"].content = "\n\n".join([*lines, m.baked_note])
                return
            row = int(b.rows[i])
            distance = read_npz_row(b.path, "distance", row)
            try:
                normal = read_npz_row(b.path, "normal16", row)
            except KeyError:  # format 1 keeps float normals
                normal = read_npz_row(b.path, "normal", row)
            g["maps"].image = map_strip(
                radiance_image(b.radiance[i], b.white),
                distance_image(distance, b.far),
                normal_image(normal, distance, b.far),
            )
            g["maps"].visible = True
            lines.append(
                f"archive row {row}; mean visible distance {b.reach[i]:.4g}. The ball at the probe: its SH "
                "irradiance E(n)/π (a white Lambertian ball lit by the probe)."
            )
            g["selected"].content = "\n\n".join(lines)
            from ..placement import fibonacci_directions  # imports JAX: not at `probeplace view --help`

            dirs = fibonacci_directions(SPHERE_POINTS).astype(np.float64)
            r = SPHERE_RADII * float(self.radii()[i])
            self.server.scene.add_point_cloud(
                "/selected/irradiance",
                points=(dirs * r).astype(np.float32),
                colors=irradiance_colours(b.sh[i], dirs, b.irradiance_white),
                # twice the points' spacing on the sphere, so they close into a surface
                point_size=2.0 * r * np.sqrt(4 * np.pi / SPHERE_POINTS),
                point_shape="circle",
                point_shading="flat",
                precision="float32",
                position=tuple(float(x) for x in p),
            )


def probe_figures(m: ViewModel, i: int) -> list[str]:
    """Probe ``i``'s coverage counts and error shares, one line each, when the run recorded them."""
    out = []
    if m.coverage is not None:
        c = m.coverage
        out.append(
            f"sees {c.seen[i]} of {c.n_coverable} coverable surface samples, {c.unique[i]} of them alone"
        )
    if m.error is not None:
        parts = []
        for comp, share in m.error.shares.items():
            mse = m.error.mse.get(comp, float("nan"))
            pct = f" ({100 * share[i] / mse:.3g} %)" if mse > 0 else ""
            parts.append(f"{comp} {share[i]:.4g}{pct}")
        out.append("share of the MSE: " + ", ".join(parts))
    return out


def start_viewer(model: ViewModel, *, host: str = "127.0.0.1", port: int = 8080) -> Viewer:
    """Serve ``model`` on ``host:port`` (viser moves to the next free port when that one is taken:
    ``Viewer.url`` has the one in use) and return at once."""
    import viser

    # viser prints its own address box whatever ``verbose`` says; the command prints the address to open
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host=host, port=port, label="probeplace view", verbose=False)
    viewer = Viewer(server, model, view_url(host, server.get_port()))
    scene = server.scene
    scene.set_up_direction("+y")
    # Lighting cheap enough for software WebGL (SwiftShader drew its first frame in 8 s with viser's
    # default environment map, prefiltered on the client, and shadow maps; 3-4 s without): no environment
    # map, no shadows (lights outside a closed room would only darken it), ambient and sky light instead.
    scene.configure_environment_map(hdri=None)
    scene.configure_default_lights(True, cast_shadow=False)
    scene.add_light_ambient("/lights/ambient", intensity=0.5)
    scene.add_light_hemisphere("/lights/sky", ground_color=(120, 120, 120), intensity=0.9)
    _set_initial_camera(server, model)
    for j, (rgb, v, f) in enumerate(
        split_by_colour(model.mesh.vertices, model.mesh.faces, model.mesh.face_rgb)
    ):
        scene.add_mesh_simple(f"/scene/part_{j}", v, f, color=rgb, side="double", flat_shading=True)
    _add_gui(viewer)
    _add_probes(viewer)
    _add_uncovered(viewer)
    _add_cameras(viewer)
    return viewer


def _add_uncovered(viewer: Viewer) -> None:
    """The coverage samples no probe sees, as red points (hidden until the checkbox is ticked)."""
    m, g = viewer.model, viewer._gui
    if m.coverage is None or not len(m.coverage.uncovered):  # full coverage: nothing to draw
        return
    pts = m.coverage.uncovered
    handle = viewer.server.scene.add_point_cloud(
        "/uncovered",
        points=pts.astype(np.float32).reshape(-1, 3),
        colors=np.tile(np.asarray(UNCOVERED_RGB, np.uint8), (len(pts), 1)),
        point_size=0.006 * m.diagonal,
        point_shape="circle",
        point_shading="flat",
        precision="float32",
        visible=False,
    )
    g["uncovered_points"] = handle
    g["show_uncovered"].on_update(lambda _: setattr(handle, "visible", g["show_uncovered"].value))


def _set_initial_camera(server, model: ViewModel) -> None:
    """Open on the evaluation's view (else the scene's first): what the error image shows, seen the same
    way; clip planes from the scene's size (viser's default far plane is 1000 units)."""
    cam = _eval_camera(model) or (model.cameras[0] if model.cameras else None)
    ic = server.initial_camera
    ic.near, ic.far = 1e-3 * model.diagonal, 100.0 * model.diagonal
    if cam is None:
        ic.look_at = tuple(0.5 * (model.lo + model.hi))
        ic.position = tuple(model.hi + 0.5 * (model.hi - model.lo))
        return
    ic.position, ic.look_at, ic.up = tuple(cam.position), tuple(cam.look_at), tuple(cam.up)
    ic.fov = float(np.radians(cam.fov_y_deg))


def _eval_camera(model: ViewModel) -> ViewCamera | None:
    if model.eval is None:
        return None
    return next((c for c in model.cameras if c.name == model.eval.view), None)


def _add_probes(viewer: Viewer) -> None:
    m = viewer.model
    if not len(m.positions):
        viewer._gui["probes"] = None
        return
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    n = len(m.positions)
    handle = viewer.server.scene.add_batched_meshes_simple(
        "/probes",
        np.asarray(ball.vertices, np.float32),
        np.asarray(ball.faces, np.uint32),
        batched_wxyzs=np.tile(np.array([1.0, 0.0, 0.0, 0.0], np.float32), (n, 1)),
        batched_positions=m.positions.astype(np.float32),
        batched_scales=viewer.radii().astype(np.float32),
        batched_colors=m.colours(COLOUR_STATUS),
        lod="off",
    )
    viewer._gui["probes"] = handle

    @handle.on_click
    def _(event) -> None:
        i = event.instance_index
        if i is None:  # viser reports instances of batched axes only: pick along the click ray
            i = pick_probe(m.positions, viewer.radii(), event.ray_origin, event.ray_direction)
        if i is not None:
            viewer.select(int(i))

    viewer._gui["show_probes"].on_update(
        lambda _: setattr(handle, "visible", viewer._gui["show_probes"].value)
    )


def _add_cameras(viewer: Viewer) -> None:
    m, scene, g = viewer.model, viewer.server.scene, viewer._gui
    ev = m.eval
    frustums = {}
    for cam in m.cameras:
        is_eval = ev is not None and cam.name == ev.view
        aspect = ev.width / ev.height if is_eval else 1.0
        frustums[cam.name] = scene.add_camera_frustum(
            f"/cameras/{cam.name}",
            fov=float(np.radians(cam.fov_y_deg)),
            aspect=aspect,
            scale=0.08 * m.diagonal,
            thickness=0.002 * m.diagonal,
            color=EVAL_RGB if is_eval else (40, 40, 40),
            wxyz=camera_wxyz(cam),
            position=tuple(cam.position),
        )
        scene.add_label(f"/cameras/{cam.name}/label", cam.name + (" (evaluation)" if is_eval else ""))

    def show(_=None) -> None:
        for f in frustums.values():
            f.visible = g["show_cameras"].value

    g["show_cameras"].on_update(show)
    if ev is None:
        return
    from PIL import Image

    def error_on_frustum(_=None) -> None:
        comp = g["component"].value
        img = np.asarray(Image.open(ev.images[comp]).convert("RGB"))
        g["error"].image = img
        vmax = ev.vmax.get(comp)
        g["error_text"].content = f"{comp}: |probe − reference|, colour bar top {vmax:.4g}" if vmax else comp
        # the PNG carries its colour bar on the right: the frustum shows the rendered image alone
        if ev.view in frustums:  # a view the scene no longer has (its sidecar changed): the panel only
            frustums[ev.view].image = img[:, : ev.width] if g["error_on_camera"].value else None

    g["component"].on_update(error_on_frustum)
    g["error_on_camera"].on_update(error_on_frustum)
    error_on_frustum()


def _add_gui(viewer: Viewer) -> None:
    m, gui, g = viewer.model, viewer.server.gui, viewer._gui
    counts = np.bincount(m.status, minlength=len(STATUS_LABELS))
    shown = [k for k in range(len(STATUS_LABELS)) if k < 3 or counts[k]]  # placement's kinds when present
    gui.add_markdown(f"**{m.title}**: {len(m.positions)} probes")
    # first: a click's answer shows without scrolling the panel
    with gui.add_folder("Selected probe"):
        g["selected"] = gui.add_markdown("Click a probe to see its maps.")
        g["maps"] = gui.add_image(
            np.zeros((2, 2, 3), np.uint8),
            label="radiance · distance (near bright, escaped blue) · normal ((n + 1) / 2)",
            format="png",
            visible=False,
        )
        if m.baked is None:
            gui.add_markdown(m.baked_note)
    with gui.add_folder("Probes"):
        g["show_probes"] = gui.add_checkbox("show probes", True)
        g["colour"] = gui.add_dropdown("colour by", m.colour_options, initial_value=COLOUR_STATUS)
        g["size"] = gui.add_dropdown("size by", m.size_options, initial_value=SIZE_UNIFORM)
        g["colour_legend"] = gui.add_markdown(m.legend(COLOUR_STATUS))
        legend = [
            f"<span style='color:rgb{tuple(int(c) for c in STATUS_RGB[k])}'>●</span> "
            f"{STATUS_LABELS[k]}: {counts[k]}"
            for k in shown
        ]
        gui.add_markdown("  \n".join(legend) + "\n\n" + m.status_note)
        if m.coverage is not None:
            n_un = len(m.coverage.uncovered)
            g["show_uncovered"] = gui.add_checkbox(
                f"uncovered surface samples ({n_un})", False, disabled=not n_un, hint=m.coverage_note
            )
            gui.add_markdown(f"*coverage*: {m.coverage_note}")
        if m.error is not None:
            gui.add_markdown(f"*error contribution*: {m.error_note}")
        for name, reason in m.unavailable.items():
            gui.add_checkbox(name, False, disabled=True, hint=reason)
            gui.add_markdown(f"*{name}*: {reason}")
    for k in ("colour", "size"):
        g[k].on_update(lambda _: viewer.restyle())
    with gui.add_folder("Cameras"):
        g["show_cameras"] = gui.add_checkbox("show the scene's views", True)
    with gui.add_folder("Evaluation"):
        if m.eval is None:
            gui.add_markdown(m.eval_note)
        else:
            g["error_on_camera"] = gui.add_checkbox("error image on the camera", False)
            g["component"] = gui.add_dropdown("component", tuple(m.eval.images), initial_value=_first(m))
            g["error"] = gui.add_image(np.zeros((2, 2, 3), np.uint8), label="error image", format="png")
            g["error_text"] = gui.add_markdown(m.eval_note)


def _first(m: ViewModel) -> str:
    return "full" if "full" in m.eval.images else next(iter(m.eval.images))


def hostname() -> str:
    """This machine's name, for the ``ssh -L`` hint."""
    return socket.gethostname()
