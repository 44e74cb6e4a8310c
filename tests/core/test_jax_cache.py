"""JAX's persistent compilation cache (issue 32, ``probeplace._core.runtime._jax_cache``): where it lives,
what it refuses, that setting it up imports no JAX, ``probeplace cache info|clear``, and that a cached
program gives the very same results as a freshly compiled one."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from probeplace._core.runtime import _jax_cache
from probeplace._core.runtime._jax_cache import ENV, cache_tag, enable_compilation_cache, resolve

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def restore_cache():
    """The suite's cache setting back after a test that moves this process's cache."""
    before = os.environ.get(ENV)
    yield
    enable_compilation_cache(before)


def _private(path: Path) -> Path:
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    path.chmod(0o700)
    return path


def test_folder_default_env_and_flag(monkeypatch, tmp_path):
    monkeypatch.delenv(ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    tag = cache_tag()
    assert tag.startswith("jax-") and len(tag.split("-")) >= 5  # jax, jaxlib, machine, CPU hash
    assert resolve().folder == tmp_path / "xdg" / "probeplace" / tag and resolve().source == "default"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/is/ignored")  # the XDG spec: only absolute paths
    assert resolve().folder == Path.home() / ".cache" / "probeplace" / tag
    monkeypatch.setenv(ENV, str(tmp_path / "mine"))
    assert resolve().folder == tmp_path / "mine" / tag and resolve().source == f"${ENV}"
    for off in ("off", "OFF", " 0 ", "none", "false"):
        monkeypatch.setenv(ENV, off)
        assert resolve().folder is None
    assert resolve(str(tmp_path / "flag")).folder == tmp_path / "flag" / tag  # the flag wins over the env
    assert resolve("off").folder is None and resolve("off").source == "--jax-cache"


def test_refuses_folders_others_can_write_to(monkeypatch, tmp_path):
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o777)
    state = _jax_cache.prepare(resolve(str(shared)))
    assert state.folder is None and "writable by every user" in state.refused
    assert not (shared / cache_tag()).exists()  # nothing created in it
    # a parent writable by all without the sticky bit: the folder could be swapped
    inner = _jax_cache.prepare(resolve(str(shared / "inner")))
    assert inner.folder is None and f"its parent {shared} is writable by every user" in inner.refused
    shared.chmod(0o1777)  # sticky (like /tmp): only the owner can rename what is in it
    assert _jax_cache.prepare(resolve(str(shared / "inner"))).folder == shared / "inner" / cache_tag()
    mine = _private(tmp_path / "mine")
    monkeypatch.setattr(os, "getuid", lambda: os.stat(mine).st_uid + 1)
    other = _jax_cache.prepare(resolve(str(mine)))
    assert other.folder is None and "owned by another user" in other.refused


def test_created_folder_is_private(tmp_path):
    state = _jax_cache.prepare(resolve(str(tmp_path / "new" / "root")))
    assert state.folder is not None and state.folder.is_dir()
    assert state.folder.stat().st_mode & 0o777 == 0o700 and state.root.stat().st_mode & 0o777 == 0o700


def test_setup_imports_no_jax(tmp_path):
    """Enabling the cache sets the variables JAX reads at import, and imports no JAX itself."""
    code = (
        "import json, os, sys\n"
        "from probeplace._core.runtime import enable_compilation_cache\n"
        "s = enable_compilation_cache()\n"
        "env = {k: v for k, v in os.environ.items() if 'CACHE' in k}\n"
        "print(json.dumps({'jax': 'jax' in sys.modules, 'env': env, 'folder': str(s.folder)}))\n"
    )
    env = {**os.environ, ENV: str(_private(tmp_path / "c"))}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    assert got["jax"] is False
    assert got["folder"] == str(tmp_path / "c" / cache_tag())
    assert got["env"]["JAX_COMPILATION_CACHE_DIR"] == got["folder"]
    assert got["env"]["JAX_ENABLE_COMPILATION_CACHE"] == "true"
    assert got["env"]["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] == "0"
    assert got["env"]["JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES"] == "-1"


def test_config_after_import_and_disabled_block(tmp_path, restore_cache):
    """With JAX imported, the config follows; every compile is kept (no time or size floor), and
    :func:`persistent_cache_disabled` keeps a block's compiles out of the cache."""
    import jax
    import jax.numpy as jnp

    state = enable_compilation_cache(str(_private(tmp_path / "c")))
    assert jax.config.jax_compilation_cache_dir == str(state.folder)
    assert jax.config.jax_persistent_cache_min_compile_time_secs == 0
    assert jax.config.jax_persistent_cache_min_entry_size_bytes == -1
    jax.block_until_ready(jax.jit(lambda x: x * 3.0 + 1.0)(jnp.ones(5)))  # microseconds to compile
    n1, _ = _jax_cache.entries(state.folder)
    assert n1 >= 1
    with _jax_cache.persistent_cache_disabled():
        jax.block_until_ready(jax.jit(lambda x: x * 5.0 - 2.0)(jnp.ones(6)))
    assert _jax_cache.entries(state.folder)[0] == n1
    jax.block_until_ready(jax.jit(lambda x: x * 7.0 - 4.0)(jnp.ones(7)))  # on again after the block
    assert _jax_cache.entries(state.folder)[0] > n1


def test_cli_cache_info_and_clear(tmp_path, capsys, restore_cache):
    from probeplace.cli import main

    folder = _private(tmp_path / "c") / cache_tag()
    other = tmp_path / "c" / "jax-0.0.1-0.0.1-x86_64-00000000"
    for f in (folder, other):
        f.mkdir(parents=True, exist_ok=True)
        (f / "jit_f-abc-cache").write_bytes(b"x" * 1000)
        (f / "keep-me.txt").write_text("not an entry")  # clear deletes JAX's entry files only
    assert main(["--jax-cache", str(tmp_path / "c"), "cache", "info"]) == 0
    out = capsys.readouterr().out
    assert f"folder:  {folder}" in out and "entries: 1" in out and f"other:   {other} (1 entries" in out
    assert main(["--jax-cache", str(tmp_path / "c"), "cache", "clear"]) == 0
    assert f"cleared {folder}: 1 entries" in capsys.readouterr().out
    assert not (folder / "jit_f-abc-cache").exists() and (folder / "keep-me.txt").exists()
    assert (other / "jit_f-abc-cache").exists()
    assert main(["--jax-cache", str(tmp_path / "c"), "cache", "clear", "--all"]) == 0
    assert not (other / "jit_f-abc-cache").exists()
    assert main(["--jax-cache", "off", "cache", "info"]) == 0
    assert "off (turned off by --jax-cache)" in capsys.readouterr().out


# --- the cache changes no result: placement + bake, cold, warm and off, compared bit for bit ---

PIPELINE = """
import hashlib, json, sys
import jax, jax.numpy as jnp, numpy as np
from jax import monitoring

events = {}
monitoring.register_event_listener(lambda name, **kw: events.__setitem__(name, events.get(name, 0) + 1))

from probeplace.placement import place
from probeplace.probes import BakeConfig, bake_probes, path_traced_radiance
from probeplace.geometry import BruteForceCaster
from probeplace.scene import cornell_box

scene = cornell_box()
method, radiance = sys.argv[1:3]
res = place(scene, method=method, budget=3, n_opt_samples=300, seed=1)
caster = BruteForceCaster(scene)
if radiance == "path":
    fn = path_traced_radiance(scene, spp=1, max_depth=2, caster=caster)
else:  # a constant sky: the bake's geometry (distance moments, inside test) without the path tracer's compile
    def fn(o, d, k):
        return jnp.full((o.shape[0], 3), 0.5, o.dtype), jnp.zeros((o.shape[0], 3), o.dtype)
cfg = BakeConfig(radiance_res=8, irradiance_res=4, moments_res=4, n_sub=1, probes_per_batch=4, progress=False)
lf = bake_probes(scene, res.probes, caster=caster, radiance_fn=fn, key=jax.random.key(0), config=cfg)
h = hashlib.sha256()
for leaf in jax.tree.leaves((res.probes, lf)):
    a = np.asarray(leaf)
    h.update(str((a.dtype, a.shape)).encode()); h.update(a.tobytes())
print(json.dumps({"digest": h.hexdigest(), "n_probes": int(res.n_probes),
                  "hits": events.get("/jax/compilation_cache/cache_hits", 0),
                  "misses": events.get("/jax/compilation_cache/cache_misses", 0),
                  "used": events.get("/jax/compilation_cache/tasks_using_cache", 0)}))
"""


def _pipeline(cache: str, method: str, radiance: str) -> dict:
    env = {**os.environ, ENV: cache, "JAX_PLATFORMS": "cpu"}
    code = "from probeplace._core.runtime import enable_compilation_cache\nenable_compilation_cache()\n"
    cmd = [sys.executable, "-c", code + PIPELINE, method, radiance]
    r = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize(
    ("method", "radiance"),
    [
        ("grid", "const"),  # ~20 s cold on 2 cores: the default run
        pytest.param("skeleton", "path", marks=pytest.mark.slow),  # + the path tracer's compile: ~60 s
    ],
)
def test_cached_programs_give_identical_results(tmp_path, method, radiance):
    """Placement + a small bake in three fresh processes: the first fills an empty cache, the second loads
    every program from it (cache hits, no miss, no new entry), the third runs with the cache off. Probe
    positions and every baked map agree to the bit."""
    root = _private(tmp_path / "jc")
    folder = root / cache_tag()
    cold = _pipeline(str(root), method, radiance)
    n_cold, _ = _jax_cache.entries(folder)
    warm = _pipeline(str(root), method, radiance)
    off = _pipeline("off", method, radiance)
    assert cold["n_probes"] == 3
    assert cold["hits"] == 0 and cold["misses"] >= 5 and n_cold >= cold["misses"]
    assert warm["hits"] >= cold["misses"] and warm["misses"] == 0, warm
    assert _jax_cache.entries(folder)[0] == n_cold  # nothing new written
    assert off["used"] == 0 and off["hits"] == 0
    assert warm["digest"] == cold["digest"] == off["digest"]


def test_explain_compiles_flag_and_variable(monkeypatch, restore_cache):
    """``--explain-compiles`` (and ``$PROBEPLACE_EXPLAIN_COMPILES``) turns on JAX's compile log and its
    cache-miss explanations, for this process and (through the environment) the ones it starts."""
    import jax

    from probeplace.cli import main

    for env in (_jax_cache.EXPLAIN_ENV, "JAX_LOG_COMPILES", "JAX_EXPLAIN_CACHE_MISSES"):
        monkeypatch.setenv(env, "")  # recorded, so that what the flag sets is undone after the test
        monkeypatch.delenv(env)
    old = jax.config.jax_log_compiles, jax.config.jax_explain_cache_misses
    try:
        assert _jax_cache.explain_compiles() is False  # nothing asked
        assert main(["--jax-cache", "off", "cache", "info"]) == 0
        assert not jax.config.jax_log_compiles
        assert main(["--explain-compiles", "--jax-cache", "off", "cache", "info"]) == 0
        assert jax.config.jax_log_compiles and jax.config.jax_explain_cache_misses
        assert os.environ[_jax_cache.EXPLAIN_ENV] == "1" and os.environ["JAX_LOG_COMPILES"] == "true"
        jax.config.update("jax_log_compiles", False)
        monkeypatch.setenv(_jax_cache.EXPLAIN_ENV, "off")
        assert _jax_cache.explain_compiles() is False
        monkeypatch.setenv(_jax_cache.EXPLAIN_ENV, "yes")
        assert _jax_cache.explain_compiles() is True and jax.config.jax_log_compiles
    finally:
        jax.config.update("jax_log_compiles", old[0])
        jax.config.update("jax_explain_cache_misses", old[1])
