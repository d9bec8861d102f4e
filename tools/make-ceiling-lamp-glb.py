#!/usr/bin/env python3
"""Writes scenes/gltf/ceiling-lamp.glb with Blender itself (its Python module, `pip install
bpy`; Blender 5.0.1 wrote the shipped file): what a modeller gets by snapping a light panel onto
a ceiling.

The model: a room made of Blender's cube, 4 x 4 x 3 m, its normals recalculated to face inside
(Mesh > Normals > Recalculate Inside); a 1 m plane rotated to face down and moved into the
ceiling's very plane, its Principled BSDF emitting (strength 5; Blender marks the material
double-sided, so the panel emits both ways); a 0.8 m cube standing on the floor; a camera in a
low corner looking up past the panel. The exporter's defaults otherwise (+Y up, cameras
included).

Usage, from the repository root:

    python3 tools/make-ceiling-lamp-glb.py [output.glb]
"""

import math
import sys

import bpy
import mathutils


def material(name, colour, emission=None):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1)
    if emission:
        bsdf.inputs["Emission Color"].default_value = (1, 1, 1, 1)
        bsdf.inputs["Emission Strength"].default_value = emission
    return m


def main(out):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_cube_add(size=2, location=(0, 0, 1.5))
    room = bpy.context.object
    room.name = "room"
    room.scale = (2, 2, 1.5)
    bpy.ops.object.transform_apply(scale=True)
    room.data.materials.append(material("walls", (0.7, 0.7, 0.7)))
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.mesh.normals_make_consistent(inside=True)
    bpy.ops.object.mode_set(mode="OBJECT")
    bpy.ops.mesh.primitive_plane_add(size=1, location=(0, 0, 3.0), rotation=(math.pi, 0, 0))
    lamp = bpy.context.object
    lamp.name = "lamp"
    bpy.ops.object.transform_apply(rotation=True)
    lamp.data.materials.append(material("lamp", (0.8, 0.8, 0.8), emission=5.0))
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.6, 0.4, 0.4))
    box = bpy.context.object
    box.name = "box"
    box.data.materials.append(material("box", (0.6, 0.3, 0.2)))
    bpy.ops.object.camera_add(location=(-1.7, -1.7, 0.8))
    camera = bpy.context.object
    target = mathutils.Vector((0.5, 0.5, 2.6))
    camera.rotation_euler = (target - camera.location).to_track_quat("-Z", "Y").to_euler()
    camera.data.angle = math.radians(80)
    bpy.context.scene.camera = camera
    bpy.ops.export_scene.gltf(filepath=out, export_format="GLB", export_cameras=True)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "scenes/gltf/ceiling-lamp.glb")
