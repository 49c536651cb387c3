#!/usr/bin/env python3
"""Writes the sky-courtyard scene: sky.hdr (a 64 x 32 equirectangular Radiance HDR sky with a
sun), courtyard.obj + courtyard.mtl (a ground square and three boxes, no emitter). The manifest,
sky-courtyard.json, is written by hand. Run from anywhere: files land next to this script.

Sky (docs/scene-manifest.md, "environment"; rows from the zenith down, the image's centre looks
along -Z): a blue gradient, brighter towards the horizon, a dim brown ground below it, and one
bright texel as the sun, 30 degrees above the horizon, to the camera's left and in front.
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
W, H = 64, 32


def sky(row, col):
    theta = (row + 0.5) / H * math.pi  # from +Y
    if theta > math.pi / 2:
        return (0.08, 0.07, 0.06)  # the ground below the horizon
    up = math.cos(theta)
    horizon, zenith = (1.0, 1.05, 1.1), (0.25, 0.45, 0.9)
    return tuple(h + (z - h) * up for h, z in zip(horizon, zenith))


def rgbe(rgb):
    m = max(rgb)
    if m < 1e-32:
        return bytes(4)
    mantissa, exponent = math.frexp(m)
    scale = mantissa * 256.0 / m
    return bytes([min(255, int(c * scale)) for c in rgb] + [exponent + 128])


def write_sky(path):
    sun_row, sun_col = 10, 22  # elevation 90 - 59 = 31 degrees, 56 degrees left of -Z
    with open(path, "wb") as f:
        f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (H, W))
        for row in range(H):
            for col in range(W):
                rgb = (400.0, 360.0, 300.0) if (row, col) == (sun_row, sun_col) else sky(row, col)
                f.write(rgbe(rgb))  # flat scanlines: stb_image reads them (no RLE marker 2 2)


def box(lo, hi):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]
    # Faces counter-clockwise seen from outside (1-based indices into v).
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    return v, faces


def write_obj(obj_path, mtl_path):
    objects = [
        ("ground", "ground", [(-4, 0, -4), (4, 0, -4), (4, 0, 4), (-4, 0, 4)], [(1, 4, 3, 2)]),
    ]
    for name, material, lo, hi in [("white_box", "white", (-1.6, 0, -1.0), (-0.4, 1.2, 0.2)),
                                   ("red_box", "red", (0.4, 0, -0.2), (1.4, 0.6, 0.8)),
                                   ("pillar", "blue", (0.6, 0, -2.2), (1.0, 2.2, -1.8))]:
        v, f = box(lo, hi)
        objects.append((name, material, v, f))
    with open(obj_path, "w") as f:
        f.write("# Written by make_sky_courtyard.py: a ground square and three boxes.\n")
        f.write("mtllib courtyard.mtl\n")
        base = 0
        for name, material, verts, faces in objects:
            f.write("o %s\nusemtl %s\n" % (name, material))
            for p in verts:
                f.write("v %g %g %g\n" % p)
            for face in faces:
                f.write("f " + " ".join(str(base + i) for i in face) + "\n")
            base += len(verts)
    with open(mtl_path, "w") as f:
        for name, kd in [("ground", (0.45, 0.42, 0.38)), ("white", (0.8, 0.8, 0.8)),
                         ("red", (0.7, 0.15, 0.1)), ("blue", (0.2, 0.3, 0.7))]:
            f.write("newmtl %s\nKd %g %g %g\n\n" % ((name,) + kd))


if __name__ == "__main__":
    write_sky(os.path.join(HERE, "sky.hdr"))
    write_obj(os.path.join(HERE, "courtyard.obj"), os.path.join(HERE, "courtyard.mtl"))
