"""Embree's 16-ray packets for coherent closest-hit queries, beside embreex's one ray at a time.

embreex binds only ``rtcIntersect1``. The geometry bake casts one ray per texel from each probe (33.5 M
rays for 128 probes at 512², issue 33), and rays of a 4×4 texel tile from one origin are as coherent as
rays get: Embree's ``rtcIntersect16`` with ``RTC_RAY_QUERY_FLAG_COHERENT`` traverses the BVH once for
the 16 of them. Measured on Sponza (4.2 M texel rays, 2 threads, this module against embreex): 13.0
against 6.1 M rays/s; in 16×1 strips instead of 4×4 tiles, 8.2 M rays/s.

This binds the Embree library that embreex loads (``embreex.libs/libembree4*``, Embree 4.4) through
ctypes: its own scene over the same triangle soup (so ``primID`` is the triangle's index, as embreex's),
the packet structure ``RTCRayHit16`` laid out as in Embree 4's ``rtcore_ray.h`` (structure of arrays,
64-byte aligned), and the loop over packets in C (``_packet_loop``, an optional extension: the GIL is
released for the whole loop, so threads cast in parallel; from Python a call per packet cost as much as
the packet). Where the library, the extension or the scene is missing, :func:`packet_scene` returns
``None`` and the caller casts through embreex.

Packets and single rays are two of Embree's traversal kernels: they agree but on rays that graze an
edge or a vertex, where Embree's (non-watertight) triangle test may let one kernel through the crack and
not the other (0.02 % of the bake's rays on Sponza; ``tests/geometry/test_embree_packets.py``).
"""

from __future__ import annotations

import ctypes
import glob
import logging
import os
import threading

import numpy as np

log = logging.getLogger(__name__)

W = 16  # rays a packet (RTCRayHit16)
# RTCRayHit16, in 4-byte words of W lanes each (Embree 4 rtcore_ray.h): the ray's org_x, org_y, org_z,
# tnear, dir_x, dir_y, dir_z, time, tfar, mask, id, flags; then the hit's Ng_x, Ng_y, Ng_z, u, v, primID,
# geomID, instID[levels], instPrimID[levels]. A packet slot of 32 rows leaves room for 6 instance levels.
_ORG, _TNEAR, _DIR, _TFAR, _MASK = 0, 3, 4, 8, 9
_U, _V, _PRIM, _GEOM = 15, 16, 17, 18
_ROWS = 32
_INVALID = 0xFFFFFFFF  # RTC_INVALID_GEOMETRY_ID
_COHERENT = 1 << 16  # RTC_RAY_QUERY_FLAG_COHERENT
_FEATURES_ALL = 0xFFFFFFFF  # RTC_FEATURE_FLAG_ALL
_BUFFER_INDEX, _BUFFER_VERTEX = 0, 1  # RTCBufferType
_FORMAT_UINT3, _FORMAT_FLOAT3 = 0x5003, 0x9003  # RTCFormat
_TRIANGLE = 0  # RTC_GEOMETRY_TYPE_TRIANGLE


def _aligned(shape, dtype, align: int = 64) -> np.ndarray:
    """A zeroed array whose data start on an ``align``-byte boundary (Embree reads packets aligned)."""
    n = int(np.prod(shape)) * np.dtype(dtype).itemsize
    raw = np.zeros(n + align, np.uint8)
    off = -raw.ctypes.data % align
    return raw[off : off + n].view(dtype).reshape(shape)


_LIB_LOCK = threading.Lock()
_LIB: list = []  # [(ctypes library, packet loop) or None], filled once


def _library():
    """Embree's library as embreex loads it and the packet loop, or ``None`` (logged once) where either is
    missing."""
    with _LIB_LOCK:
        if not _LIB:
            _LIB.append(_load())
        return _LIB[0]


def embree_packets_available() -> bool:
    """Whether Embree's packets can be cast here (``env.json`` records it: on rays that graze an edge the
    packets and the single rays may answer differently, see the module docstring)."""
    return _library() is not None


def _load():
    try:
        import embreex

        from . import _packet_loop
    except ImportError as e:  # no embreex, or no C compiler when probeplace was installed
        log.info("Embree packets unavailable (%s): casting one ray at a time", e)
        return None
    libs = sorted(
        glob.glob(os.path.join(os.path.dirname(embreex.__path__[0]), "embreex.libs", "libembree4*"))
    )
    if not libs:
        log.info("Embree packets unavailable: embreex's libembree4 not found; casting one ray at a time")
        return None
    vp, u32, sz = ctypes.c_void_p, ctypes.c_uint, ctypes.c_size_t
    try:
        lib = ctypes.CDLL(libs[0])  # the one embreex has loaded: the same handle
        for name, res, args in (
            ("rtcNewDevice", vp, [ctypes.c_char_p]),
            ("rtcGetDeviceError", ctypes.c_int, [vp]),
            ("rtcReleaseDevice", None, [vp]),
            ("rtcNewScene", vp, [vp]),
            ("rtcCommitScene", None, [vp]),
            ("rtcReleaseScene", None, [vp]),
            ("rtcNewGeometry", vp, [vp, ctypes.c_int]),
            ("rtcSetSharedGeometryBuffer", None, [vp, ctypes.c_int, u32, ctypes.c_int, vp, sz, sz, sz]),
            ("rtcCommitGeometry", None, [vp]),
            ("rtcAttachGeometry", u32, [vp, vp]),
            ("rtcReleaseGeometry", None, [vp]),
            ("rtcIntersect16", None, [vp, vp, vp, vp]),
        ):
            f = getattr(lib, name)
            f.restype, f.argtypes = res, args
    except (OSError, AttributeError) as e:  # a library that does not load, or lacks a function
        log.warning("Embree packets unavailable (%s): casting one ray at a time", e)
        return None
    return lib, _packet_loop


class PacketScene:
    """An Embree scene of its own over a triangle soup, queried in 16-ray packets (see the module
    docstring). Build with :func:`packet_scene`."""

    def __init__(self, lib, loop, triangles: np.ndarray):
        self._lib, self._loop = lib, loop
        # shared buffers: Embree reads them in place, so they live as long as the scene
        self._vertices = np.ascontiguousarray(triangles.reshape(-1, 3), np.float32)
        self._indices = np.arange(len(self._vertices), dtype=np.uint32).reshape(-1, 3)
        self._device = lib.rtcNewDevice(None)
        self._scene = None
        if not self._device:
            raise RuntimeError("rtcNewDevice failed")
        self._scene = lib.rtcNewScene(self._device)
        geometry = lib.rtcNewGeometry(self._device, _TRIANGLE)
        v, i = self._vertices, self._indices
        lib.rtcSetSharedGeometryBuffer(
            geometry, _BUFFER_VERTEX, 0, _FORMAT_FLOAT3, v.ctypes.data, 0, 12, len(v)
        )
        lib.rtcSetSharedGeometryBuffer(
            geometry, _BUFFER_INDEX, 0, _FORMAT_UINT3, i.ctypes.data, 0, 12, len(i)
        )
        lib.rtcCommitGeometry(geometry)
        lib.rtcAttachGeometry(self._scene, geometry)
        lib.rtcReleaseGeometry(geometry)
        lib.rtcCommitScene(self._scene)
        if (err := lib.rtcGetDeviceError(self._device)) != 0:
            raise RuntimeError(f"Embree error {err} building the packet scene")
        self._fn = ctypes.cast(lib.rtcIntersect16, ctypes.c_void_p).value
        self._valid = _aligned((W,), np.int32)
        self._valid[:] = -1  # every lane active (a short batch is padded with copies of its last ray)
        self._args = _aligned((16,), np.uint32)  # RTCIntersectArguments, zero past its first two fields
        self._args[0], self._args[1] = _COHERENT, _FEATURES_ALL  # flags, feature_mask; no context, filter

    def __del__(self):
        if getattr(self, "_scene", None):
            self._lib.rtcReleaseScene(self._scene)
        if getattr(self, "_device", None):
            self._lib.rtcReleaseDevice(self._device)

    def intersect(self, origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray) -> dict:
        """Closest hits of rays ``tnear = 0`` to ``tfar`` (all float32 (n, 3) / (n,)), consecutive rays in
        one packet: embreex's ``run(..., output=1)`` fields ``tfar`` (unchanged on a miss), ``primID``
        (−1 on a miss), ``u``, ``v``. Called from several threads at once, each with its own rays."""
        n = len(origins)
        if n == 0:
            return {"tfar": np.zeros(0, np.float32), "primID": np.zeros(0, np.int32),
                    "u": np.zeros(0, np.float32), "v": np.zeros(0, np.float32)}  # fmt: skip
        p = -(-n // W)
        if n % W:  # the last packet filled with copies of the last ray
            pad = np.minimum(np.arange(p * W), n - 1)
            origins, directions, tfar = origins[pad], directions[pad], tfar[pad]
        buf = _aligned((p, _ROWS, W), np.float32)
        for k in range(3):
            buf[:, _ORG + k] = origins[:, k].reshape(p, W)
            buf[:, _DIR + k] = directions[:, k].reshape(p, W)
        buf[:, _TFAR] = tfar.reshape(p, W)
        words = buf.view(np.uint32)
        words[:, _MASK] = 0xFFFFFFFF
        words[:, _GEOM] = _INVALID  # Embree 4 requires it set before the query
        self._loop.cast(
            self._fn,
            self._valid.ctypes.data,
            self._scene,
            buf.ctypes.data,
            p,
            _ROWS * W * 4,
            self._args.ctypes.data,
        )
        hit = words[:, _GEOM].reshape(-1)[:n] != _INVALID
        prim = words[:, _PRIM].reshape(-1)[:n].view(np.int32)
        return {
            "tfar": buf[:, _TFAR].reshape(-1)[:n],
            "primID": np.where(hit, prim, -1).astype(np.int32),
            "u": buf[:, _U].reshape(-1)[:n],
            "v": buf[:, _V].reshape(-1)[:n],
        }


def packet_scene(triangles: np.ndarray) -> PacketScene | None:
    """:class:`PacketScene` over ``triangles`` (n, 3, 3), or ``None`` where Embree's packets are unavailable
    (no embreex library, no compiled packet loop, or Embree refused the scene: logged)."""
    found = _library()
    if found is None:
        return None
    try:
        return PacketScene(*found, triangles)
    except RuntimeError as e:
        log.warning("Embree packets unavailable (%s): casting one ray at a time", e)
        return None
