"""Scenes: loaders, built-in scenes, materials, lights and views."""

from ._build import build_scene as build_scene
from ._build import crease_normals as crease_normals
from ._build import make_camera as make_camera
from ._build import make_materials as make_materials
from ._build import make_sun as make_sun
from ._cornell import cornell_box as cornell_box
