"""A real bake (probes.bake_probes, constant radiance in a closed box room) → save_probes → export.

Oracle: with incident radiance L ≡ 1 everywhere, irradiance is π for every normal (∫ cos = π), so the
SH exported from the .npz must give E(n) = π, and the DDGI irradiance atlas must hold π in every texel,
up to the quadrature error over the 16² bake texels: < 1e-3 for the SH (smooth integrand), 0.3 % for
the clamped cosine max(0, n·ω) whose kink the texel grid resolves to O(1/R²).

Marked slow: compiling the bake takes ~40 s on 2 CPU cores.
"""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ProbeSet
from probeplace.cli import main
from probeplace.export import import_probes, read_exr, sh_irradiance
from probeplace.export._ddgi import unpack_atlas
from probeplace.geometry import BruteForceCaster
from probeplace.probes import BakeConfig, bake_probes, save_probes
from probeplace.scene import build_scene, make_materials
from probeplace.scene._primitives import box

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    v, f = box(np.array([0.0, 0.0, 0.0]), np.array([4.0, 3.0, 5.0]))
    room = build_scene(
        "export_room", v, f[:, ::-1], np.zeros(len(f), int), make_materials(["wall"], np.full((1, 3), 0.5))
    )
    probes = ProbeSet(
        pos_world=jnp.asarray([[1.0, 1.0, 1.0], [3.0, 2.0, 4.0], [2.0, 1.5, 2.5]], jnp.float32),
        active=jnp.asarray([True, True, False]),
        method="manual",
    )

    def constant(origins, directions, key):
        return jnp.ones((origins.shape[0], 3), origins.dtype), jnp.zeros((origins.shape[0], 3), origins.dtype)

    cfg = BakeConfig(radiance_res=16, irradiance_res=4, moments_res=8, n_sub=1, progress=False)
    lf = bake_probes(
        room, probes, caster=BruteForceCaster(room), radiance_fn=constant, key=jax_key(), config=cfg
    )
    return save_probes(tmp_path_factory.mktemp("bake") / "room.npz", lf), lf


def jax_key():
    import jax

    return jax.random.key(0)


def test_sh_from_a_real_bake_gives_pi(tmp_path, baked):
    npz, lf = baked
    assert main(["export", str(npz), "--format", "usd", "--out", str(tmp_path / "p.usda")]) == 0
    back = import_probes(tmp_path / "p.usda")
    np.testing.assert_array_equal(back.positions, np.asarray(lf.pos_world))
    np.testing.assert_array_equal(back.active, [True, True, False])
    normals = np.eye(3)
    e = sh_irradiance(back.sh, np.concatenate([normals, -normals]))
    np.testing.assert_allclose(e, np.pi, rtol=1e-3)


def test_ddgi_from_a_real_bake(tmp_path, baked):
    npz, lf = baked
    out = tmp_path / "d.json"
    assert main(["export", str(npz), "--format", "ddgi", "--out", str(out), "--distance-res", "8"]) == 0
    side = json.loads(out.read_text())
    assert side["probe_count"] == 2
    exr = read_exr(tmp_path / "d.irradiance.exr")
    tiles = unpack_atlas(np.stack([exr["R"], exr["G"], exr["B"]], -1), 2, 8, side["tiles_per_row"])
    np.testing.assert_allclose(tiles, np.pi, rtol=5e-3)  # clamped-cosine quadrature at 16²: 0.3 %
    exr = read_exr(tmp_path / "d.distance.exr")
    tiles = unpack_atlas(np.stack([exr["R"], exr["G"]], -1), 2, 10, side["tiles_per_row"])
    np.testing.assert_array_equal(tiles, np.asarray(lf.moments)[:2])  # bake res == tile res: copied
