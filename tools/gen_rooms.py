#!/usr/bin/env python3
"""Generates the SCENE10-like, INVISIBLEDATE-like, BATHROOM-like, SCENE5-like and CONFERENCE-like test
scenes as MGF (chapter-4 estimators, docs/results/estimators.md; caustic splitting,
docs/results/caustic_splitting.md; overmodulation, docs/results/conference.md).

SCENE10 (Wald 1999, §5): a 10x10 array of small diffuse rooms, each with its own ceiling light,
doors between neighbouring rooms. INVISIBLEDATE: two rooms side by side; the viewed room has no
light of its own and is lit only through a narrow gap of a nearly closed door from the next room.

BATHROOM-like (§4.6): a small bathroom lit by two lamps inside clear glass bulbs (a glass shell
around an emitting sphere), so every photon passes glass before its first diffuse hit: the direct
light is entirely caustic, and shadow rays cannot reach the lamps. SCENE5-like: a glass sphere of
96 % transmission on a floor under one small ceiling light, its caustic beside it.

CONFERENCE-like (§3.3.5, §5): a meeting room with a long table, chairs and six ceiling panels, and
two small, very bright exit signs above the doors, each under a little hood: the hood and the
sign's housing sit right at the emitter and collect a dense cluster of its photons, where the
radiance estimate's 1/(πr²) overmodulates (the thesis's "exit" letters on the sign).

    tools/gen_rooms.py            # writes scenes/{scene10,invisibledate,bathroom,scene5,conference}/*.mgf

Units: metres, y up. Walls are single two-sided faces.
"""
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent


class Mgf:
    def __init__(self):
        self.lines = []
        self.n = 0

    def material(self, name, rd=None, ed=None, rs=None, ts=None, ir=None, cxy=None):
        """`cxy` (CIE x, y) colours every component; the default `c` is neutral grey."""
        self.lines += [f"m {name} =", f"  cxy {cxy[0]} {cxy[1]}" if cxy else "  c"]
        if rd is not None:
            self.lines.append(f"  rd {rd}")
        if ed is not None:
            self.lines.append(f"  ed {ed}")
        if rs is not None:
            self.lines.append(f"  rs {rs} 0")
        if ts is not None:
            self.lines.append(f"  ts {ts} 0")
        if ir is not None:
            self.lines.append(f"  ir {ir} 0")

    def sphere(self, centre, radius):
        """MGF sph; a negative radius points the normals (the front faces) inwards."""
        name = f"v{self.n}"
        self.n += 1
        self.lines += [f"v {name} =", f"  p {centre[0]:.4f} {centre[1]:.4f} {centre[2]:.4f}",
                       f"sph {name} {radius:.4f}"]

    def box(self, x0, x1, y0, y1, z0, z1):
        """Closed axis-aligned box, faces outwards."""
        self.quad_y(x0, x1, z0, z1, y1, down=False)
        self.quad_y(x0, x1, z0, z1, y0, down=True)
        self.face((x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0))  # -z
        self.face((x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1))  # +z
        self.face((x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0))  # -x
        self.face((x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1))  # +x

    def use(self, name):
        self.lines.append(f"m {name}")

    def face(self, *points):
        names = []
        for p in points:
            name = f"v{self.n}"
            self.n += 1
            self.lines += [f"v {name} =", f"  p {p[0]:.4f} {p[1]:.4f} {p[2]:.4f}"]
            names.append(name)
        self.lines.append("f " + " ".join(names))

    def quad_y(self, x0, x1, z0, z1, y, down):
        """Horizontal rectangle at height y; front face down (-y) or up (+y)."""
        if down:
            self.face((x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1))
        else:
            self.face((x0, y, z0), (x0, y, z1), (x1, y, z1), (x1, y, z0))

    def wall_x(self, x, z0, z1, y0, y1):
        """Wall in the plane x = const."""
        self.face((x, y0, z0), (x, y0, z1), (x, y1, z1), (x, y1, z0))

    def wall_z(self, z, x0, x1, y0, y1):
        self.face((x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z))

    def wall_x_with_gap(self, x, z0, z1, height, gap_z0, gap_z1, gap_top):
        self.wall_x(x, z0, gap_z0, 0, height)
        self.wall_x(x, gap_z1, z1, 0, height)
        self.wall_x(x, gap_z0, gap_z1, gap_top, height)

    def wall_z_with_gap(self, z, x0, x1, height, gap_x0, gap_x1, gap_top):
        self.wall_z(z, x0, gap_x0, 0, height)
        self.wall_z(z, gap_x1, x1, 0, height)
        self.wall_z(z, gap_x0, gap_x1, gap_top, height)

    def room(self, w, d, height, floor="floor"):
        """A closed w x height x d room from the origin: floor (material `floor`), "ceiling" and
        four "wall"s, each facing in."""
        self.use(floor)
        self.quad_y(0, w, 0, d, 0.0, down=False)
        self.use("ceiling")
        self.quad_y(0, w, 0, d, height, down=True)
        self.use("wall")
        self.wall_x(0, 0, d, 0, height)
        self.wall_x(w, 0, d, 0, height)
        self.wall_z(0, 0, w, 0, height)
        self.wall_z(d, 0, w, 0, height)

    def write(self, path, header):
        path.write_text("".join(f"# {h}\n" for h in header) + "\n".join(self.lines) + "\n")


def scene10(rooms=10, size=4.0, height=2.5, door=0.9, door_top=2.0, light=0.5):
    m = Mgf()
    m.material("floor", rd=0.45)
    m.material("wall", rd=0.7)
    m.material("ceiling", rd=0.8)
    # ed in lm/m²: Le = ed/(π·179) ≈ 10 W/(m²·sr) for 5622.
    m.material("lamp", ed=5622)
    total = rooms * size
    m.use("floor")
    m.quad_y(0, total, 0, total, 0.0, down=False)
    m.use("ceiling")
    m.quad_y(0, total, 0, total, height, down=True)
    m.use("wall")
    for i in range(rooms + 1):  # walls x = i·size and z = i·size
        c = i * size
        for j in range(rooms):
            a, b = j * size, (j + 1) * size
            mid = (a + b) / 2
            if i in (0, rooms):
                m.wall_x(c, a, b, 0, height)
                m.wall_z(c, a, b, 0, height)
            else:
                m.wall_x_with_gap(c, a, b, height, mid - door / 2, mid + door / 2, door_top)
                m.wall_z_with_gap(c, a, b, height, mid - door / 2, mid + door / 2, door_top)
    m.use("lamp")
    for i in range(rooms):
        for j in range(rooms):
            cx, cz = (i + 0.5) * size, (j + 0.5) * size
            m.quad_y(cx - light / 2, cx + light / 2, cz - light / 2, cz + light / 2, height - 0.01, down=True)
    return m


def invisible_date(size=4.0, height=2.5, gap=0.05, door_top=2.0):
    """Room A (x in [0,4]) is viewed; room B (x in [4,8]) holds the light. The door between them
    is open by a `gap`-wide slit only."""
    m = Mgf()
    m.material("floor", rd=0.45)
    m.material("wall", rd=0.7)
    m.material("ceiling", rd=0.8)
    m.material("lamp", ed=20000)
    m.room(2 * size, size, height)
    mid = size / 2
    m.wall_x_with_gap(size, 0, size, height, mid - gap / 2, mid + gap / 2, door_top)
    m.use("lamp")
    m.quad_y(1.5 * size - 0.3, 1.5 * size + 0.3, mid - 0.3, mid + 0.3, height - 0.01, down=True)
    return m


def bathroom(w=3.0, d=3.0, height=2.5, bulb=0.2, glass=0.015, lamp=0.12):
    """BATHROOM-like: a 3 x 2.5 x 3 m room (x, y up, z); a mirror on the back wall (z = 0) above a
    vanity, a bathtub along the left wall, two lamps on the back wall's left and right of the
    mirror, each an emitting sphere inside a clear glass bulb (outer surface facing out, inner
    surface facing in: the glass is a shell and the lamp sits in air)."""
    m = Mgf()
    m.material("tiles", rd=0.6)
    m.material("wall", rd=0.75)
    m.material("ceiling", rd=0.8)
    m.material("tub", rd=0.85)
    m.material("vanity", rd=0.5)
    m.material("mirror", rs=0.9)
    m.material("bulb_glass", ts=1, ir=1.5)
    # ed in lm/m²: Le = ed/(π·179) ≈ 40 W/(m²·sr).
    m.material("lamp", ed=22500)
    m.room(w, d, height, floor="tiles")
    m.use("tub")
    m.box(0.0, 0.75, 0.0, 0.55, 0.6, 2.4)
    m.use("vanity")
    m.box(1.1, 2.3, 0.0, 0.85, 0.0, 0.5)
    m.use("mirror")
    m.face((1.2, 1.05, 0.005), (2.2, 1.05, 0.005), (2.2, 2.05, 0.005), (1.2, 2.05, 0.005))
    for x in (0.8, 2.6):
        centre = (x, 1.75, 0.35)
        m.use("bulb_glass")
        m.sphere(centre, bulb)
        m.sphere(centre, -(bulb - glass))
        m.use("lamp")
        m.sphere(centre, lamp)
    return m


def scene5(size=3.0, height=2.5, radius=0.3, light=0.3, pedestal=0.3):
    """SCENE5-like: a glass sphere (96 % specular transmission, ior 1.5) on a thin pedestal in a
    3 x 2.5 x 3 m room; one small ceiling light off to the side, so the sphere focuses it into a
    caustic on the floor beside the pedestal."""
    m = Mgf()
    m.material("floor", rd=0.6)
    m.material("wall", rd=0.7)
    m.material("ceiling", rd=0.8)
    m.material("glass", ts=0.96, ir=1.5)
    m.material("pedestal", rd=0.5)
    m.material("lamp", ed=40000)
    m.room(size, size, height)
    m.use("pedestal")
    m.box(size / 2 - 0.08, size / 2 + 0.08, 0.0, pedestal, size / 2 - 0.08, size / 2 + 0.08)
    m.use("glass")
    m.sphere((size / 2, pedestal + radius, size / 2), radius)
    m.use("lamp")
    lx, lz = size / 2 - 1.2, size / 2 - 0.3
    m.quad_y(lx - light / 2, lx + light / 2, lz - light / 2, lz + light / 2, height - 0.01, down=True)
    return m


def conference(w=8.0, d=6.0, height=3.0, panel=0.6, sign_w=0.28, sign_h=0.08, sign_y=2.85):
    """CONFERENCE-like: an 8 x 3 x 6 m room (x, y up, z); a 4 x 1.2 m table with eight chairs, six
    0.6 m ceiling panels (Le = 10), and on the far wall (x = 8) two doors, each with an exit sign
    above it, under the ceiling: a 0.36 x 0.2 m housing whose front carries a 0.28 x 0.08 m emitter
    of Le = 100 (green), under a 0.2 m deep hood with side cheeks whose top is 5 cm below the
    ceiling. The signs are 10x the panels' radiance on 1/16 of a panel's area, and much of their
    light lands on the hood's underside: a dense photon cluster
    facing down like the ceiling 5 cm above it, so the ceiling's k-nearest-photon disks (which
    keep photons arriving from the front side, §4.1) take it in: overmodulation (§3.3.5)."""
    m = Mgf()
    m.material("carpet", rd=0.3)
    m.material("wall", rd=0.7)
    m.material("ceiling", rd=0.8)
    m.material("door", rd=0.35)
    m.material("wood", rd=0.5)
    m.material("chair", rd=0.4)
    m.material("housing", rd=0.8)
    # ed in lm/m²: Le = ed/(π·179) ≈ 10 W/(m²·sr) for 5622 (the panels).
    m.material("panel", ed=5622)
    # Exit signs: luminance Le = 56235/(π·179) = 100 W/(m²·sr), green (CIE x 0.3, y 0.5: inside the
    # sRGB gamut, so the RGB emission keeps that luminance).
    m.material("exit_sign", ed=56235, cxy=(0.3, 0.5))
    m.room(w, d, height, floor="carpet")
    # The table: top and four legs.
    m.use("wood")
    tx0, tx1, tz0, tz1 = 2.0, 6.0, 2.4, 3.6
    m.box(tx0, tx1, 0.72, 0.76, tz0, tz1)
    for x in (tx0 + 0.1, tx1 - 0.16):
        for z in (tz0 + 0.1, tz1 - 0.16):
            m.box(x, x + 0.06, 0.0, 0.72, z, z + 0.06)
    # Four chairs along each long side, facing the table: seat, back, legs.
    m.use("chair")
    for x in (2.5, 3.5, 4.5, 5.5):
        for side in (-1, 1):
            zc = (tz0 - 0.35) if side < 0 else (tz1 + 0.35)
            x0, x1, z0, z1 = x - 0.22, x + 0.22, zc - 0.22, zc + 0.22
            m.box(x0, x1, 0.43, 0.47, z0, z1)
            bz = z0 if side < 0 else z1 - 0.04  # the back on the side away from the table
            m.box(x0, x1, 0.47, 0.95, bz, bz + 0.04)
            for lx in (x0, x1 - 0.03):
                for lz in (z0, z1 - 0.03):
                    m.box(lx, lx + 0.03, 0.0, 0.43, lz, lz + 0.03)
    m.use("panel")
    for x in (2.0, 4.0, 6.0):
        for z in (2.0, 4.0):
            m.quad_y(x - panel / 2, x + panel / 2, z - panel / 2, z + panel / 2, height - 0.01, down=True)
    for zc in (1.25, 4.75):
        m.use("door")  # 0.9 x 2.1 m, 1 cm in front of the wall
        m.wall_x(w - 0.01, zc - 0.45, zc + 0.45, 0.0, 2.1)
        # Housing 6 cm deep on the wall, 0.2 m high around sign_y; the hood (a top plate and two
        # cheeks, 0.2 m deep).
        y0, y1 = sign_y - 0.1, sign_y + 0.1
        m.use("housing")
        m.box(w - 0.06, w, y0, y1, zc - 0.18, zc + 0.18)
        m.face((w - 0.2, y1, zc - 0.2), (w - 0.2, y1, zc + 0.2), (w, y1, zc + 0.2), (w, y1, zc - 0.2))
        m.face((w - 0.2, y0, zc - 0.2), (w - 0.2, y1, zc - 0.2), (w, y1, zc - 0.2), (w, y0, zc - 0.2))
        m.face((w - 0.2, y0, zc + 0.2), (w, y0, zc + 0.2), (w, y1, zc + 0.2), (w - 0.2, y1, zc + 0.2))
        # The emitter, 1 mm in front of the housing, facing the room (-x).
        m.use("exit_sign")
        m.wall_x(w - 0.061, zc - sign_w / 2, zc + sign_w / 2, sign_y - sign_h / 2, sign_y + sign_h / 2)
    return m


def main():
    scene10().write(ROOT / "scenes/scene10/scene10.mgf",
                    ["SCENE10-like: 10x10 diffuse rooms (4 x 4 x 2.5 m), one 0.5 m ceiling light each,",
                     "0.9 x 2.0 m doors between neighbours. Generated by tools/gen_rooms.py (photonfarm)."])
    invisible_date().write(ROOT / "scenes/invisibledate/invisibledate.mgf",
                           ["INVISIBLEDATE-like: two 4 x 4 x 2.5 m rooms; the left one is lit only through a",
                            "5 cm door gap from the right one. Generated by tools/gen_rooms.py (photonfarm)."])
    (ROOT / "scenes/bathroom").mkdir(exist_ok=True)
    bathroom().write(ROOT / "scenes/bathroom/bathroom.mgf",
                     ["BATHROOM-like: 3 x 2.5 x 3 m; two lamps inside clear glass bulbs (every photon passes",
                      "glass first), a mirror, a tub and a vanity. Generated by tools/gen_rooms.py (photonfarm)."])
    (ROOT / "scenes/scene5").mkdir(exist_ok=True)
    scene5().write(ROOT / "scenes/scene5/scene5.mgf",
                   ["SCENE5-like: a 96 %-transmissive glass sphere on a pedestal in a 3 x 2.5 x 3 m room, one",
                    "small ceiling light. Generated by tools/gen_rooms.py (photonfarm)."])
    (ROOT / "scenes/conference").mkdir(exist_ok=True)
    conference().write(ROOT / "scenes/conference/conference.mgf",
                       ["CONFERENCE-like: 8 x 3 x 6 m meeting room, a table and eight chairs, six ceiling panels,",
                        "two small very bright exit signs under hoods above the doors (overmodulation, Wald 1999",
                        "3.3.5). Generated by tools/gen_rooms.py (photonfarm)."])


if __name__ == "__main__":
    main()
