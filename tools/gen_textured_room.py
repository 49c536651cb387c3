#!/usr/bin/env python3
"""Generates scenes/textured-room/: a glTF 2.0 binary (.glb) scene with image textures, for pf's
texture path (docs/renderer.md, "Textures"; docs/gltf.md), with python3's standard library only.

The room of tools/gen_gltf_room.py (same camera, walls, panel and spot) with its floor and back
wall textured:
  * floor: baseColorTexture `checker.png`, an external 8-bit PNG next to the .glb (8 x 8 texels of
    two greys, REPEAT, four repeats across the floor through TEXCOORD_0 beyond [0, 1]): the scene
    bundle must ship it (scene_bundle.h reads a .glb's JSON chunk for its uris);
  * back wall: baseColorTexture embedded in the .glb's buffer (a bufferView image, 16 x 4 texels of
    vertical colour stripes, CLAMP_TO_EDGE), times a baseColorFactor of 0.9.

    tools/gen_textured_room.py    # writes scenes/textured-room/textured-room.glb + checker.png

Deterministic (no timestamps): the same bytes on every run.
"""
import json
import pathlib
import struct
import sys
import zlib

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import gen_gltf_room as room  # noqa: E402  (the shared builder and geometry helpers)

OUT = room.ROOT / "scenes" / "textured-room"


def png(width, height, rgb_rows):
    """An 8-bit RGB PNG (no filter, zlib level 9) of rows of (r, g, b) tuples."""
    raw = b"".join(b"\x00" + bytes(c for px in row for c in px) for row in rgb_rows)

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")


def vec2(b, uvs):
    data = b"".join(struct.pack("<2f", *t) for t in uvs)
    b.accessors.append({"bufferView": b._view(data, 34962), "componentType": room.FLOAT, "count": len(uvs),
                        "type": "VEC2"})
    return len(b.accessors) - 1


def textured_quad(b, corners, normal, uvs, material):
    p, n, i = [], [], []
    room.quad(corners, normal, p, n, i)
    prim = b.primitive(p, n, i, room.U16, material)
    prim["attributes"]["TEXCOORD_0"] = vec2(b, uvs)
    return prim


def main():
    b = room.Builder()
    checker = png(8, 8, [[(200, 200, 200) if (x // 2 + y // 2) % 2 == 0 else (60, 60, 60) for x in range(8)]
                         for y in range(8)])
    stripes = png(16, 4, [[[(220, 60, 40), (230, 200, 60), (60, 120, 220), (240, 240, 240)][x // 4]
                           for x in range(16)] for _ in range(4)])
    while len(b.bin) % 4:
        b.bin.append(0)
    stripes_view = len(b.views)
    b.views.append({"buffer": 0, "byteOffset": len(b.bin), "byteLength": len(stripes)})
    b.bin += stripes

    materials = [
        room.WHITE, room.RED, room.GREEN, room.LAMP,
        {"name": "CheckerFloor", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0,
                                                          "roughnessFactor": 1}},
        {"name": "StripedWall", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.9, 0.9, 1],
                                                         "baseColorTexture": {"index": 1}, "metallicFactor": 0,
                                                         "roughnessFactor": 1}},
    ]
    white, red, green, lamp, floor, wall = range(6)
    structure = room.room(b, white, red, green)
    # The room's first primitive holds floor, ceiling and back wall: replaced by the ceiling alone
    # and two textured quads.
    p, n, i = [], [], []
    room.quad([(-2, 3, -2), (2, 3, -2), (2, 3, 2), (-2, 3, 2)], (0, -1, 0), p, n, i)
    structure["primitives"][0] = b.primitive(p, n, i, room.U32, white)
    structure["primitives"].append(textured_quad(
        b, [(-2, 0, 2), (2, 0, 2), (2, 0, -2), (-2, 0, -2)], (0, 1, 0), [(0, 4), (4, 4), (4, 0), (0, 0)], floor))
    structure["primitives"].append(textured_quad(
        b, [(-2, 0, -2), (2, 0, -2), (2, 3, -2), (-2, 3, -2)], (0, 0, 1), [(0, 1), (1, 1), (1, 0), (0, 0)], wall))
    meshes = [structure, room.cube(b, white), room.panel(b, lamp)]
    box_position = [-0.8, 0.6, -0.5]
    spot_position = [1.4, 2.8, 1.2]
    nodes = [
        {"name": "Room", "mesh": 0},
        {"name": "Box", "mesh": 1, "translation": box_position, "rotation": room.rotation_y(25),
         "scale": [0.6, 1.2, 0.6]},
        {"name": "CeilingPanel", "mesh": 2, "translation": [0, 2.99, -0.3]},
        {"name": "Spot", "translation": spot_position,
         "rotation": room.look_rotation([box_position[k] - spot_position[k] for k in range(3)]),
         "extensions": {"KHR_lights_punctual": {"light": 0}}},
        {"name": "Camera", "camera": 0, "translation": [0, 1.6, 6.2], "rotation": room.rotation_x(-2)},
    ]
    gltf = {
        "asset": {"version": "2.0", "generator": "photonfarm tools/gen_textured_room.py"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "Spot", "type": "spot", "color": [1.0, 0.9, 0.75], "intensity": 4098,
             "spot": {"innerConeAngle": 0.349066, "outerConeAngle": 0.523599}}]}},
        "scene": 0,
        "scenes": [{"name": "Scene", "nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "textures": [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 1}],
        "images": [{"uri": "checker.png"}, {"bufferView": stripes_view, "mimeType": "image/png"}],
        "samplers": [{"wrapS": 10497, "wrapT": 10497}, {"wrapS": 33071, "wrapT": 33071}],
        "cameras": [{"name": "Camera", "type": "perspective",
                     "perspective": {"yfov": 0.7, "aspectRatio": 1.25, "znear": 0.1, "zfar": 100}}],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{"byteLength": len(b.bin)}],
    }
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary = bytes(b.bin) + b"\x00" * (-len(b.bin) % 4)
    body = (struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(binary), b"BIN\x00") + binary)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "textured-room.glb").write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)
    (OUT / "checker.png").write_bytes(checker)
    print("wrote %s (%d bytes) and checker.png" % (OUT / "textured-room.glb", 12 + len(body)))


if __name__ == "__main__":
    main()
