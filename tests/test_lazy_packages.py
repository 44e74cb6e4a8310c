"""``probeplace.scene``, ``probeplace.render`` and ``probeplace.view`` load their JAX (or viser) modules on
first use (PEP 562), so the command-line parsers and ``probeplace scenes`` start without JAX; every name
they exported when they imported everything eagerly still imports, to the object its private module
defines."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

# The export lists of the eager ``__init__`` files this replaced (commit cf7dc27), and names added since.
SCENE_NAMES = """build_scene crease_normals make_camera make_materials make_sun cornell_box courtyard
KNOWN_SCENES SCENE_EXTENSIONS SCENE_PATH_ENV SceneEntry find_scene_file list_scenes load_scene
load_scene_file looks_like_path scene_config_layers scene_search_path derived_views BUILTIN_SCENES
PreviewMesh preview_mesh srgb8
ROOMS_DARK_ROOM_BOUNDS ROOMS_LIT_ROOM_BOUNDS ROOMS_WALL_THICKNESS rooms SIDECAR_SUFFIX CameraSpec
EmitterSpec MaterialSpec SceneConfig SunSpec merge_scene_configs no_light_hint parse_scene_config
read_sidecar sidecar_path apply_scene_config parse_camera parse_sky parse_sun
scene_overrides DAYLIGHT_SKY_RADIANCE DAYLIGHT_SUN_IRRADIANCE sun_direction
sun_from_irradiance TEMPLE_UNDER_STAIRS_BOX temple axis_angle_rotation transform_scene
scene_layers camera_origin scene_summary read_gltf_json""".split()
RENDER_NAMES = """ALPHA_MIN BrdfParams BrdfSample brdf_params eval_brdf ggx_d lobe_probability pdf_brdf
sample_brdf sample_ggx_vndf schlick_fresnel smith_g1 camera_basis camera_ray camera_rays load_exr save_exr
save_png save_render tonemap COMPONENTS LightSample LightTable light_table sample_light
best_mitsuba_variant mitsuba_scene_dict BACKEND_CHOICES BACKENDS RayRadiance RenderConfig RenderResult
default_caster render resolve_backend trace_rays N_UNIFORMS make_frame path_uniforms power_heuristic
seed_from_key to_local to_world load_mitsuba RAY_EPS sample_cosine_hemisphere""".split()
VIEW_NAMES = """hostname ViewInput check_scene_found resolve_input STATUS_LABELS STATUS_RGB ViewCamera
ViewModel load_view_model Viewer camera_wxyz pick_probe start_viewer""".split()
PACKAGES = {"probeplace.scene": SCENE_NAMES, "probeplace.render": RENDER_NAMES, "probeplace.view": VIEW_NAMES}


@pytest.mark.parametrize("package", list(PACKAGES))
def test_every_old_name_still_imports(package):
    names = PACKAGES[package]
    mod = importlib.import_module(package)
    assert set(mod.__all__) == set(names), set(mod.__all__) ^ set(names)
    assert set(names) <= set(dir(mod))
    ns: dict = {}
    exec(f"from {package} import {', '.join(names)}", ns)  # the spelling callers use
    for name in names:
        assert ns[name] is getattr(mod, name), name
    for name, private in mod._LAZY.items():  # each lazy name comes from the module the table names
        assert getattr(importlib.import_module(f"{package}.{private}"), name) is ns[name], name
    with pytest.raises(AttributeError, match="no_such_name"):
        mod.no_such_name


def test_builtin_scenes_mapping_loads_factories_lazily():
    from probeplace.scene import BUILTIN_SCENES, cornell_box
    from probeplace.scene.builtin._registry import BUILTIN_SCENE_FACTORIES

    assert list(BUILTIN_SCENES) == list(BUILTIN_SCENE_FACTORIES)
    assert BUILTIN_SCENES["cornell_box"] is cornell_box
    assert "nope" not in BUILTIN_SCENES
    with pytest.raises(KeyError):
        BUILTIN_SCENES["nope"]


@pytest.mark.parametrize("package", list(PACKAGES))
def test_importing_the_package_imports_no_jax(package):
    code = f"import sys, {package}; print(sorted(m for m in sys.modules if m.split('.')[0] == 'jax'))"
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "[]", res.stdout
