"""The scene file loaders, each handing :func:`~probeplace.scene.load_scene` a ``RawScene``
(``scene._raw``): glTF 2.0 / GLB (``_gltf``), Wavefront OBJ + MTL (``_obj``) and PLY (``_ply``, its
structure checked first by ``_ply_check``).

This ``__init__`` is the group's face for the rest of ``scene``; it imports trimesh and JAX, so only the
lazily loaded ``_load`` (and ``read_gltf_json``) reach it."""

from ._gltf import load_gltf as load_gltf
from ._gltf import read_gltf_json as read_gltf_json
from ._obj import load_obj as load_obj
from ._ply import load_ply as load_ply
