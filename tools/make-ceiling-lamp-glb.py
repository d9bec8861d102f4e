#!/usr/bin/env python3
"""Writes scenes/gltf/ceiling-lamp.glb with Blender itself (its Python module, `pip install
bpy`; Blender 5.0.1 wrote the shipped files): what a modeller gets by snapping a light panel onto
a ceiling. With `--as-modelled`, the room's normals stay as Blender's cube has them, facing
outward (scenes/gltf/ceiling-lamp-outward.glb), which Blender still shows lit inside.

The model: a room made of Blender's cube, 4 x 4 x 3 m, its normals recalculated to face inside
(Mesh > Normals > Recalculate Inside); a 1 m plane rotated to face down and moved into the
ceiling's very plane, its Principled BSDF emitting (strength 5; Blender marks the material
double-sided, so the panel emits both ways); a 0.8 m cube standing on the floor; a camera in a
low corner looking up past the panel. The exporter's defaults otherwise (+Y up, cameras
included).

Usage, from the repository root:

    python3 tools/make-ceiling-lamp-glb.py [output.glb]
    python3 tools/make-ceiling-lamp-glb.py --as-modelled scenes/gltf/ceiling-lamp-outward.glb
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


def main(out, inside):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_cube_add(size=2, location=(0, 0, 1.5))
    room = bpy.context.object
    room.name = "room"
    room.scale = (2, 2, 1.5)
    bpy.ops.object.transform_apply(scale=True)
    room.data.materials.append(material("walls", (0.7, 0.7, 0.7)))
    if inside:
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
    args = [a for a in sys.argv[1:] if a != "--as-modelled"]
    main(args[0] if args else "scenes/gltf/ceiling-lamp.glb", "--as-modelled" not in sys.argv)
