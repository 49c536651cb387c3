#!/usr/bin/env python3
"""Generates scenes/gltf-room/gltf-room.gltf + gltf-room.bin: a glTF 2.0 test scene for pf's glTF
loader (docs/gltf.md), written with python3's standard library only (Blender is not needed).

An open-fronted room (white floor, ceiling and back wall, red left wall, green right wall), a
tall box turned 25 degrees about y and scaled by its node, a smooth metal sphere placed through
a two-level node hierarchy, an emissive ceiling panel (KHR_materials_emissive_strength), a spot
light on the box (KHR_lights_punctual, candela) and a perspective camera in front of the
opening. It exercises what the loader reads: TRS transforms composed down a hierarchy, smooth
normals, indices of all three widths (u8 box, u16 sphere, u32 room), several primitives per
mesh, materials from pbrMetallicRoughness, emission and punctual lights.

    tools/gen_gltf_room.py        # writes scenes/gltf-room/gltf-room.{gltf,bin}

Units: metres, y up (glTF's convention). The output is deterministic (no timestamps).
"""
import json
import math
import pathlib
import struct

ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "scenes" / "gltf-room"

FLOAT, U8, U16, U32 = 5126, 5121, 5123, 5125


class Builder:
    """One binary buffer; views and accessors appended to it, 4-byte aligned."""

    def __init__(self):
        self.bin = bytearray()
        self.views = []
        self.accessors = []

    def _view(self, data, target):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.views.append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data), "target": target})
        self.bin += data
        return len(self.views) - 1

    def vec3(self, points):
        data = b"".join(struct.pack("<3f", *p) for p in points)
        acc = {"bufferView": self._view(data, 34962), "componentType": FLOAT, "count": len(points), "type": "VEC3"}
        # min/max are required for POSITION (glTF 2.0 spec, §3.7.2.1); harmless for NORMAL.
        acc["min"] = [min(p[i] for p in points) for i in range(3)]
        acc["max"] = [max(p[i] for p in points) for i in range(3)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def indices(self, idx, component):
        fmt = {U8: "B", U16: "H", U32: "I"}[component]
        data = struct.pack("<%d%s" % (len(idx), fmt), *idx)
        acc = {"bufferView": self._view(data, 34963), "componentType": component, "count": len(idx), "type": "SCALAR"}
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def primitive(self, positions, normals, idx, component, material):
        return {"attributes": {"POSITION": self.vec3(positions), "NORMAL": self.vec3(normals)},
                "indices": self.indices(idx, component), "material": material}


def quad(corners, normal, pos, nor, idx):
    """Appends a quad (corners counter-clockwise seen from the side `normal` points to)."""
    base = len(pos)
    pos += corners
    nor += [normal] * 4
    idx += [base, base + 1, base + 2, base, base + 2, base + 3]


def room(b, white, red, green):
    """x in [-2, 2], y in [0, 3], z in [-2, 2]; open towards +z. Three primitives (u32 indices)."""
    prims = []
    p, n, i = [], [], []
    quad([(-2, 0, 2), (2, 0, 2), (2, 0, -2), (-2, 0, -2)], (0, 1, 0), p, n, i)  # floor
    quad([(-2, 3, -2), (2, 3, -2), (2, 3, 2), (-2, 3, 2)], (0, -1, 0), p, n, i)  # ceiling
    quad([(-2, 0, -2), (2, 0, -2), (2, 3, -2), (-2, 3, -2)], (0, 0, 1), p, n, i)  # back wall
    prims.append(b.primitive(p, n, i, U32, white))
    p, n, i = [], [], []
    quad([(-2, 0, 2), (-2, 0, -2), (-2, 3, -2), (-2, 3, 2)], (1, 0, 0), p, n, i)  # left wall
    prims.append(b.primitive(p, n, i, U32, red))
    p, n, i = [], [], []
    quad([(2, 0, -2), (2, 0, 2), (2, 3, 2), (2, 3, -2)], (-1, 0, 0), p, n, i)  # right wall
    prims.append(b.primitive(p, n, i, U32, green))
    return {"name": "Room", "primitives": prims}


def cube(b, material):
    """The cube [-0.5, 0.5]^3 with flat faces (24 vertices, u8 indices)."""
    p, n, i = [], [], []
    for axis in range(3):
        for sign in (-1, 1):
            normal = [0, 0, 0]
            normal[axis] = sign
            u = [0, 0, 0]
            v = [0, 0, 0]
            u[(axis + 1) % 3] = 1
            v[(axis + 2) % 3] = 1
            if sign < 0:
                u, v = v, u
            c = [0.5 * normal[k] for k in range(3)]
            corners = []
            for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                corners.append(tuple(c[k] + 0.5 * su * u[k] + 0.5 * sv * v[k] for k in range(3)))
            quad(corners, tuple(normal), p, n, i)
    return {"name": "Box", "primitives": [b.primitive(p, n, i, U8, material)]}


def sphere(b, material, segments=32, rings=16):
    """A unit UV sphere with smooth normals (u16 indices)."""
    p, n, i = [], [], []
    for r in range(rings + 1):
        theta = math.pi * r / rings
        for s in range(segments + 1):
            phi = 2 * math.pi * s / segments
            d = (math.sin(theta) * math.cos(phi), math.cos(theta), -math.sin(theta) * math.sin(phi))
            p.append(d)
            n.append(d)
    for r in range(rings):
        for s in range(segments):
            a = r * (segments + 1) + s
            c = a + segments + 1
            if r > 0:
                i += [a, c, a + 1]
            if r < rings - 1:
                i += [a + 1, c, c + 1]
    return {"name": "Sphere", "primitives": [b.primitive(p, n, i, U16, material)]}


def panel(b, material):
    """A 1 x 1 m panel facing down (-y), centred at the origin."""
    p, n, i = [], [], []
    quad([(-0.5, 0, -0.5), (0.5, 0, -0.5), (0.5, 0, 0.5), (-0.5, 0, 0.5)], (0, -1, 0), p, n, i)
    return {"name": "Panel", "primitives": [b.primitive(p, n, i, U16, material)]}


def rotation_y(degrees):
    h = math.radians(degrees) / 2
    return [0, math.sin(h), 0, math.cos(h)]


def rotation_x(degrees):
    h = math.radians(degrees) / 2
    return [math.sin(h), 0, 0, math.cos(h)]


def look_rotation(direction):
    """The unit quaternion that turns -z onto `direction` (the light's or camera's axis)."""
    length = math.sqrt(sum(c * c for c in direction))
    d = [c / length for c in direction]
    f = (0.0, 0.0, -1.0)
    axis = (f[1] * d[2] - f[2] * d[1], f[2] * d[0] - f[0] * d[2], f[0] * d[1] - f[1] * d[0])
    cos_angle = sum(f[k] * d[k] for k in range(3))
    w = math.sqrt((1 + cos_angle) / 2)
    s = 1 / (2 * w)
    return [axis[0] * s, axis[1] * s, axis[2] * s, w]


# The room's materials, shared with tools/gen_textured_room.py.
WHITE = {"name": "White", "pbrMetallicRoughness": {"baseColorFactor": [0.75, 0.75, 0.75, 1], "metallicFactor": 0,
                                                   "roughnessFactor": 1}}
RED = {"name": "Red", "pbrMetallicRoughness": {"baseColorFactor": [0.63, 0.065, 0.05, 1], "metallicFactor": 0,
                                               "roughnessFactor": 1}}
GREEN = {"name": "Green", "pbrMetallicRoughness": {"baseColorFactor": [0.14, 0.45, 0.091, 1], "metallicFactor": 0,
                                                   "roughnessFactor": 1}}
LAMP = {"name": "Lamp", "emissiveFactor": [1, 0.95, 0.85],
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 6}}}


def main():
    b = Builder()
    materials = [
        WHITE, RED, GREEN,
        {"name": "Gold", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.78, 0.34, 1], "metallicFactor": 1,
                                                  "roughnessFactor": 0.3}},
        LAMP,
    ]
    white, red, green, gold, lamp = range(5)
    meshes = [room(b, white, red, green), cube(b, white), sphere(b, gold), panel(b, lamp)]
    box_position = [-0.8, 0.6, -0.5]
    spot_position = [1.4, 2.8, 1.2]
    nodes = [
        {"name": "Room", "mesh": 0},
        {"name": "Box", "mesh": 1, "translation": box_position, "rotation": rotation_y(25), "scale": [0.6, 1.2, 0.6]},
        # The sphere's world centre is (0.9, 0.5, 0.3), radius 0.5: the parent's scale halves the
        # child's offset and size.
        {"name": "SphereGroup", "translation": [0.9, 0, 0.3], "scale": [0.5, 0.5, 0.5], "children": [3]},
        {"name": "Sphere", "mesh": 2, "translation": [0, 1, 0]},
        {"name": "CeilingPanel", "mesh": 3, "translation": [0, 2.99, -0.3]},
        {"name": "Spot", "translation": spot_position,
         "rotation": look_rotation([box_position[k] - spot_position[k] for k in range(3)]),
         "extensions": {"KHR_lights_punctual": {"light": 0}}},
        {"name": "Camera", "camera": 0, "translation": [0, 1.6, 6.2], "rotation": rotation_x(-2)},
    ]
    gltf = {
        "asset": {"version": "2.0", "generator": "photonfarm tools/gen_gltf_room.py"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            # 4098 cd / 683 lm/W = 6 W/sr inside 20 degrees, falling to 0 at 30 (docs/gltf.md).
            {"name": "Spot", "type": "spot", "color": [1.0, 0.9, 0.75], "intensity": 4098,
             "spot": {"innerConeAngle": math.radians(20), "outerConeAngle": math.radians(30)}}]}},
        "scene": 0,
        "scenes": [{"name": "Scene", "nodes": [0, 1, 2, 4, 5, 6]}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "cameras": [{"name": "Camera", "type": "perspective",
                     "perspective": {"yfov": 0.7, "aspectRatio": 1.25, "znear": 0.1, "zfar": 100}}],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{"byteLength": len(b.bin), "uri": "gltf-room.bin"}],
    }
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "gltf-room.bin").write_bytes(bytes(b.bin))
    (OUT / "gltf-room.gltf").write_text(json.dumps(gltf, indent=1) + "\n")
    triangles = sum(b.accessors[p["indices"]]["count"] // 3 for m in meshes for p in m["primitives"])
    print("wrote %s (%d triangles, %d bytes of buffer)" % (OUT / "gltf-room.gltf", triangles, len(b.bin)))


if __name__ == "__main__":
    main()
