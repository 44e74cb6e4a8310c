"""The same scene in Mitsuba 3, for cross-checking the reference path tracer (dev dependency only).

:func:`mitsuba_scene_dict` turns a :class:`~probeplace._core.Scene` with *diffuse* materials and area
lights into a Mitsuba ``load_dict`` description: one Wavefront OBJ per material (the triangles exactly
as ours, flat face normals), a two-sided ``diffuse`` BSDF with the base colour (our renderer shades both
sides of a surface; Mitsuba's ``diffuse`` alone is black from behind), a one-sided ``area`` emitter with
the material's emission on the emissive meshes, a constant environment for the sky, a ``perspective``
sensor with the camera's vertical field of view and a ``box`` reconstruction filter (our pixel
estimator), Mitsuba's ``path`` integrator with the same ``max_depth`` / ``rr_depth``.

:func:`best_mitsuba_variant` picks the fastest RGB variant that loads here: ``llvm_ad_rgb`` needs an
LLVM shared library (Debian: ``apt-get install libllvm19``), ``scalar_rgb`` always works.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._core import Camera, ConfigError, Scene

# Fastest first. The CUDA variant is not listed: the reference comparison is a CPU one.
_VARIANTS = ("llvm_ad_rgb", "scalar_rgb")


def best_mitsuba_variant(prefer: tuple[str, ...] = _VARIANTS) -> str:
    """Set and return the first Mitsuba variant of ``prefer`` that loads (ImportError if none does)."""
    import mitsuba as mi

    errors = []
    for v in prefer:
        if v not in mi.variants():
            errors.append(f"{v}: not compiled in")
            continue
        try:
            mi.set_variant(v)
            # The LLVM backend only fails when a kernel is first built: force one.
            if v.startswith("llvm"):
                import drjit as dr

                dr.eval(mi.Float(1.0) + 1.0)
            return v
        except Exception as e:
            errors.append(f"{v}: {e}")
    raise ImportError("no usable Mitsuba variant: " + "; ".join(errors))


def _write_obj(path: Path, tris: np.ndarray) -> None:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in tris.reshape(-1, 3).astype(np.float64).tolist()]
    lines += [f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}" for i in range(tris.shape[0])]
    path.write_text("\n".join(lines) + "\n")


def mitsuba_scene_dict(
    scene: Scene,
    camera: Camera,
    *,
    width: int,
    height: int,
    spp: int,
    max_depth: int,
    rr_depth: int = 5,
    workdir: str | Path,
    integrator: dict | None = None,
) -> dict:
    """A Mitsuba 3 ``load_dict`` description of ``scene`` seen by ``camera`` (call after setting a variant).

    Args:
        scene: the scene; every material must be diffuse (metallic 0) and the scene must have no sun
            (Mitsuba's sun differs from our constant-radiance disk).
        camera: the view.
        width, height, spp: film size and samples per pixel (``independent`` sampler).
        max_depth, rr_depth: path length limit and Russian-roulette start, our conventions = Mitsuba's.
        workdir: folder for the per-material OBJ files.
        integrator: override the integrator dict (e.g. wrap ``path`` in ``moment``).

    Raises:
        ConfigError: a metallic material or a sun.
    """
    import mitsuba as mi

    if scene.sun is not None:
        raise ConfigError(
            "mitsuba_scene_dict: scenes with a sun are not supported (no matching Mitsuba emitter)"
        )
    metallic = np.asarray(scene.materials.metallic)
    if np.any(metallic > 0):
        raise ConfigError("mitsuba_scene_dict: only diffuse materials (metallic = 0) are supported")
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    tris = np.asarray(scene.triangles, np.float64)
    tri_mat = np.asarray(scene.tri_material)
    base = np.asarray(scene.materials.base_color, np.float64)
    emission = np.asarray(scene.materials.emission, np.float64)
    d: dict = {"type": "scene"}
    for m, name in enumerate(scene.materials.names):
        sel = tri_mat == m
        if not np.any(sel):
            continue
        path = workdir / f"mat{m}.obj"
        _write_obj(path, tris[sel])
        shape = {
            "type": "obj",
            "filename": str(path),
            "face_normals": True,
            "bsdf": {
                "type": "twosided",
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": base[m].tolist()}},
            },
        }
        if np.max(emission[m]) > 0:
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": emission[m].tolist()}}
        d[f"shape_{m}_{name}"] = shape
    sky = np.asarray(scene.sky_radiance, np.float64)
    if np.max(sky) > 0:
        d["sky"] = {"type": "constant", "radiance": {"type": "rgb", "value": sky.tolist()}}
    pos = np.asarray(camera.position, np.float64).tolist()
    target = np.asarray(camera.look_at, np.float64).tolist()
    up = np.asarray(camera.up, np.float64).tolist()
    d["sensor"] = {
        "type": "perspective",
        "fov": float(camera.fov_y_deg),
        "fov_axis": "y",
        "to_world": mi.ScalarTransform4f().look_at(origin=pos, target=target, up=up),
        "sampler": {"type": "independent", "sample_count": spp},
        "film": {
            "type": "hdrfilm",
            "width": width,
            "height": height,
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
        },
    }
    d["integrator"] = integrator or {"type": "path", "max_depth": max_depth, "rr_depth": rr_depth}
    return d
