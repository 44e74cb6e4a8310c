"""``report.html``: the experiment report as one self-contained page (issue 36).

Written by ``_report.make_report`` beside ``report.md``, in the same partial folder (so atomically). The
page needs no server and no network: it opens from ``file://`` and holds

* report.md itself, rendered by markdown-it-py from the same Markdown lines (so the tables are the same
  tables), its charts inlined as ``data:`` URIs;
* per scene, a 3D view of the placements (three.js r170, vendored in ``_vendor/three`` and inlined): the
  scene's triangles in their display colours (``scene.preview_mesh``), loaded once per scene, and the
  probes of each representative run as spheres in the method's chart colour, one set at a time;
* per scene, images a person can judge: for each representative run the reference, the probe-lit image,
  the perfect trace and the error, side by side at one scale (one exposure per block, one error scale),
  upscaled to at least 256 CSS px without smoothing, with the resolution and sample counts.

A *representative run* is one run per method at the comparison count (:func:`representative_runs`). The
page's script (``_report_assets/view3d.js``) exposes ``window.probeplaceViews`` for the browser test.
"""

from __future__ import annotations

import base64
import gzip
import html
import io
import json
import math
from importlib import resources
from pathlib import Path

import numpy as np

from .._core import RunFiles
from ..evaluate import RunSettings
from ._report_data import COMPONENTS, PRIMARY, comparator, evaluation, figure_words, grid_count, mse, pose

#: Narrowest an image is shown (CSS px): a 64 × 64 evaluation is too small to judge at its own size.
MIN_CSS_PX = 256
#: Widest an image is shown (CSS px), so that four fit side by side on a laptop screen.
MAX_CSS_PX = 420
#: (component, its block open by default): the primary metric's block is open, the others folded.
BLOCKS = tuple((c, c == PRIMARY) for c in COMPONENTS)
#: The reference's 99th percentile is shown at this tone-mapped level: bright, without clipping most pixels.
TARGET_LEVEL = 0.8
#: Probe marker radius as a share of the scene's bounding-box diagonal: it sets how the marker shrinks with
#: distance (13 px across at the Cornell view); the page holds it between 9 and 22 CSS px across.
PROBE_RADIUS = 0.008


def _asset(*parts: str) -> str:
    return resources.files(__package__).joinpath(*parts).read_text(encoding="utf-8")


def _data_uri(data: bytes, mime: str = "image/png") -> str:
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def _png(rgb: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def markdown_html(lines: list[str], folder: Path) -> str:
    """report.md's ``lines`` as HTML (CommonMark with tables, raw HTML off); each image whose file is in
    ``folder`` is inlined as a ``data:`` URI, so the page holds its charts."""
    from markdown_it import MarkdownIt

    md = MarkdownIt("commonmark", {"html": False}).enable("table")
    tokens = md.parse("\n".join(lines))
    for tok in tokens:
        for child in tok.children or ():
            if child.type == "image" and (src := folder / str(child.attrGet("src"))).is_file():
                child.attrSet("src", _data_uri(src.read_bytes()))
    return md.renderer.render(tokens, md.options, {})


def representative_runs(runs: list[dict], scene: str, labels: list[str]) -> list[dict]:
    """One run of each method on ``scene``: the unperturbed pose if any run has it (else the pose most
    runs share), at the comparison count — the grid's (``grid_count``, as in the equal-count table), else
    the commonest count — or, for a method not run there, its count nearest in log; the lowest seed."""
    rs = [r for r in runs if r["scene"] == scene]
    poses = [(tuple(r.get("translate_frac") or ()), r.get("rotate_deg")) for r in rs]
    base = [p for r, p in zip(rs, poses, strict=True) if pose(r) == "base"]
    want = base[0] if base else max(set(poses), key=poses.count)
    rs = [r for r, p in zip(rs, poses, strict=True) if p == want]
    rs = [r for r in rs if r["n_probes"] > 0]  # an empty placement has nothing to show
    if not rs:
        return []
    grid = [r for r in rs if r["label"] == comparator()]
    counts = [r["n_probes"] for r in rs]
    count = grid_count(grid) if grid else max(sorted(set(counts)), key=counts.count)
    reps = []
    for lab in labels:
        if mine := [r for r in rs if r["label"] == lab]:
            near = min(mine, key=lambda r: (abs(math.log(r["n_probes"] / count)), r["n_probes"], r["seed"]))
            reps.append(min((r for r in mine if r["n_probes"] == near["n_probes"]), key=lambda r: r["seed"]))
    return reps


def _display_px(width: int) -> int:
    """CSS width of an image ``width`` px wide: an integer multiple up to :data:`MIN_CSS_PX` (pixels stay
    square blocks), at most :data:`MAX_CSS_PX`."""
    return min(width * math.ceil(MIN_CSS_PX / width), max(MAX_CSS_PX, MIN_CSS_PX)) if width else MIN_CSS_PX


def _sample_line(r: dict, shape: tuple) -> str:
    """The run's image size and sample counts (its evaluation's settings and ``samples``, the runner's
    ``bake_samples``)."""
    ev, b = evaluation(r), r.get("bake_samples") or {}
    s = RunSettings() if ev is None else ev.settings
    chosen = None if ev is None or ev.samples is None else ev.samples.reference_chosen_by

    def n(v, unit):
        return "—" if v is None else f"{v} {unit}"

    return (
        f"{shape[1]} × {shape[0]} px, view {s.view or '—'} · reference {n(s.spp, 'paths/px')}"
        f"{f' ({chosen})' if chosen else ''}, max depth {'—' if s.max_depth is None else s.max_depth}"
        f" · glossy reference (common random numbers) {n(s.glossy_ref_spp, 'paths')}"
        f" · probe shading {n(s.glossy_spp, 'glossy samples/px')}"
        f" · bake {n(b.get('spp'), 'paths per texel ray')}"
    )


def _image_cell(img: bytes | None, width: int, aspect: str, title: str, why: str = "") -> str:
    """One image of a row at ``width`` CSS px, or a grey box of its size saying it was not saved."""
    if img is None:
        box = f'<div style="width:{width}px;aspect-ratio:{aspect}">not saved</div>'
        return f'<figure class="shot missing">{box}<figcaption>{title}</figcaption></figure>'
    return (
        f'<figure class="shot"><img src="{_data_uri(img)}" style="width:{width}px" alt="{title}">'
        f"<figcaption>{title}{why}</figcaption></figure>"
    )


def _component_block(reps: list[dict], layers: dict, comp: str, opened: bool) -> str:
    """One component's images for every representative run: reference, probe-lit, perfect trace (glossy
    only) and |probe − reference| side by side, one exposure and one error scale for the whole block.
    A run without ``images.exr`` shows its saved PNGs (exposure 0, the error on its own scale)."""
    from ..evaluate import false_colour
    from ..render import tonemap

    kinds = ["ref", "probe", *(["perfect_trace"] if comp == "glossy_indirect" else []), "error"]
    titles = {"ref": "reference", "probe": "probe-lit", "perfect_trace": "perfect trace", "error": "error"}
    refs = [lay[f"ref_{comp}"] for r in reps if f"ref_{comp}" in (lay := layers[r["run"]])]
    errs = [lay[f"error_{comp}"].mean(axis=-1) for r in reps if f"error_{comp}" in (lay := layers[r["run"]])]
    p99 = float(np.percentile(np.concatenate([x.ravel() for x in refs]), 99)) if refs else 0.0
    stops = int(np.clip(math.floor(math.log2(TARGET_LEVEL / p99)), -16, 24)) if p99 > 0 else 0
    vmax = float(np.percentile(np.concatenate([x.ravel() for x in errs]), 99)) if errs else 0.0
    rows = []
    for r in reps:
        lay, ev = layers[r["run"]], r["dir"] / RunFiles.eval_dir
        shape = next((a.shape for a in lay.values()), None)
        width = _display_px(shape[1]) if shape else MIN_CSS_PX
        aspect = f"{shape[1]} / {shape[0]}" if shape else "1"
        cells = []
        for kind in kinds:
            name = f"{kind}_{comp}"
            if name in lay and kind == "error":
                img = _png(false_colour(lay[name], vmax if vmax > 0 else None, bar=False))
            elif name in lay:
                img = _png(tonemap(lay[name], float(stops)))
            else:  # no EXR layer: the evaluation's own PNG, on its own scale
                png = ev / (f"{name}_false.png" if kind == "error" else f"{name}.png")
                img = png.read_bytes() if png.is_file() else None
            cells.append(_image_cell(img, width, aspect, titles[kind], "" if name in lay else " (saved PNG)"))
        mse_c = mse(r, comp)
        head = (
            f"<b>{html.escape(r['label'])}</b> · {r['n_probes']} probes · seed {r['seed']} · "
            f"{html.escape(figure_words('mse', comp))} {'—' if mse_c is None else f'{mse_c:.3g}'}"
        )
        size = _sample_line(r, shape) if shape else "no images.exr"
        rows.append(
            f'<div class="run"><p class="runhead">{head}<br><small>{html.escape(size)}</small></p>'
            f'<div class="shots">{"".join(cells)}</div></div>'
        )
    scale = (
        f"Exposure {stops:+d} stops for every image of this block (the references' 99th percentile shown "
        f"at {TARGET_LEVEL:.0%}); error: |probe − reference| (mean RGB), viridis 0 … {vmax:.3g} "
        "(the block's 99th percentile), one scale for every run."
    )
    return (
        f'<details class="component"{" open" if opened else ""}><summary>{comp.replace("_", " ")}</summary>'
        f'<p class="note">{html.escape(scale)}</p>{"".join(rows)}</details>'
    )


def _layers(r: dict) -> dict[str, np.ndarray]:
    """The run's evaluation images (``eval/images.exr``) by name; empty when it saved none."""
    from ..render import load_exr

    exr = r["dir"] / RunFiles.eval_dir / RunFiles.images
    if not exr.is_file():
        return {}
    # the EXR's unnamed main layer is the evaluation's probe_full (evaluate.write_evaluation)
    return {k or "probe_full": np.asarray(v, np.float32) for k, v in load_exr(exr).items()}


def _b64_gzip(a: np.ndarray) -> str:
    """An array's bytes gzipped (mtime 0: the same report gives the same page) and base64-encoded; the
    page inflates them with the browser's DecompressionStream (Sponza's 262k triangles: about 2.6 MB)."""
    return base64.b64encode(gzip.compress(np.ascontiguousarray(a).tobytes(), mtime=0)).decode("ascii")


def _camera(scene, view: str | None) -> dict:
    """The evaluation's camera (``eval.view``) as the 3D view's start, so it shows what the images show
    (the scene's first view without one; a view from the front of the bounding box without any). Its
    ``look_at`` is moved along the line of sight to the depth of the scene's centre: the view orbits
    about the middle of the scene rather than a point on its near wall."""
    lo, hi = np.asarray(scene.bounds, float)
    c = 0.5 * (lo + hi)
    d = float(np.linalg.norm(hi - lo))
    cams = {cam.name: cam for cam in scene.views}
    cam = cams.get(view) or next(iter(cams.values()), None)
    if cam is None:
        pos, look, up, fov = c + np.array([0.0, 0.3 * d, 1.5 * d]), c, np.array([0.0, 1.0, 0.0]), 45.0
    else:
        pos, look = np.asarray(cam.position, float), np.asarray(cam.look_at, float)
        up, fov = np.asarray(cam.up, float), float(cam.fov_y_deg)
        sight = (look - pos) / max(float(np.linalg.norm(look - pos)), 1e-30)
        look = pos + sight * max(float(np.dot(c - pos, sight)), 1e-3 * d)
    return {"position": pos.tolist(), "look_at": look.tolist(), "up": up.tolist(), "fov_y_deg": fov}


def _view_payload(scene, reps: list[dict], col: dict) -> dict:
    """The 3D view's data: the scene's triangles (vertices float32, faces uint32, a colour index into a
    palette of the face colours: a scene has few materials) and each representative run's probes."""
    from matplotlib.colors import to_hex

    from .._core import load_probe_set
    from ..scene import preview_mesh

    mesh = preview_mesh(scene)
    palette, index = np.unique(mesh.face_rgb, axis=0, return_inverse=True)
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    sets = []
    for r in reps:
        probes, _ = load_probe_set(r["dir"] / RunFiles.probes)
        pos = np.asarray(probes.pos_world, float)[np.asarray(probes.active)]
        name = f"{r['label']} · {len(pos)} probes · seed {r['seed']}"
        sets.append({"name": name, "run": r["run"], "colour": to_hex(col[r["label"]]), "pos": pos.tolist()})
    return {
        "scene": scene.name,
        "vertices": _b64_gzip(mesh.vertices.astype("<f4")),
        "faces": _b64_gzip(mesh.faces.astype("<u4")),
        "colour_index": _b64_gzip(index.reshape(-1).astype("<u1" if len(palette) <= 256 else "<u2")),
        "index_bytes": 1 if len(palette) <= 256 else 2,
        "palette": palette.tolist(),
        "camera": _camera(scene, None if (ev := evaluation(reps[0])) is None else ev.settings.view),
        "radius": PROBE_RADIUS * float(np.linalg.norm(hi - lo)),
        "sets": sets,
    }


def _scene_section(scene_name: str, reps: list[dict], scene, col: dict, i: int) -> tuple[str, str]:
    """A scene's 3D view (or the one line saying why there is none) and its image blocks."""
    esc = html.escape(scene_name)
    if isinstance(scene, str):  # _report_data.load_scenes could not load it: say why, in one line
        why = f'<p class="why">3D view unavailable: {html.escape(scene)}</p>'
        view = f'<section class="view3d"><h3>{esc}</h3>{why}</section>'
    else:
        data = json.dumps(_view_payload(scene, reps, col)).replace("<", "\\u003c")  # no "</script>" inside
        view = (
            f'<section class="view3d" id="view-{i}"><h3>{esc}</h3><div class="toolbar"></div>'
            '<canvas width="800" height="500"></canvas><p class="hint">drag: orbit · shift-drag or '
            "right-drag: pan · wheel: zoom · double-click: back to the evaluation's camera</p>"
            f'<script type="application/json" class="view-data">{data}</script></section>'
        )
    layers = {r["run"]: _layers(r) for r in reps}
    blocks = "".join(_component_block(reps, layers, c, opened) for c, opened in BLOCKS)
    images = f'<section class="images"><h3>{esc}</h3>{blocks}</section>'
    return view, images


def write_report_html(
    out: Path, runs: list[dict], labels: list[str], head: list[str], body: list[str], scenes: dict
) -> Path:
    """Write ``out/report.html`` from report.md's lines ``head`` (title) and ``body`` (charts, tables) and
    the figures already in ``out``, with each scene's 3D view and images between them (module docstring).
    ``scenes``: run name → scene, or why it could not be loaded (``_report_data.load_scenes``)."""
    from ._report_charts import colours

    col = colours(labels)
    views, images = [], []
    for i, name in enumerate(sorted({r["scene"] for r in runs})):
        if not (reps := representative_runs(runs, name, labels)):
            continue
        view, imgs = _scene_section(name, reps, scenes[reps[0]["run"]], col, i)
        views.append(view)
        images.append(imgs)
    three = any('class="view-data"' in v for v in views)
    page = [
        '<!doctype html><html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(head[0].removeprefix('# '))}</title>",
        f"<style>{_asset('_report_assets', 'report.css')}</style></head>",
        "<body><main>",
        markdown_html(head, out),
        "<h2>Placements in 3D</h2>",
        "<p>One run per method at the comparison count (the grid's, else the commonest; seed 0 where run), "
        "its probes over the scene's triangles in the method's chart colour; the buttons switch between "
        "them. Probes are drawn through walls unless unticked.</p>",
        *views,
        "<h2>Images (one run per method)</h2>",
        "<p>The same runs, each evaluation's images side by side: reference, probe-lit, the perfect trace "
        "(the probes read at the exact glossy hit: the representation's own error) and the error.</p>",
        *images,
        markdown_html(body, out),
        "</main>",
    ]
    # the library as inert text: the page's module imports it from a blob (file:// allows no import)
    if three:
        page += [
            '<script type="text/plain" id="three-js">',
            _asset("_vendor", "three", "three.module.min.js"),
            "</script>",
            f'<script type="module">{_asset("_report_assets", "view3d.js")}</script>',
        ]
    page.append("</body></html>")
    path = out / "report.html"
    path.write_text("\n".join(page), encoding="utf-8")
    return path
