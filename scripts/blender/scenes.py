"""Randomised scene builders for the Blender world. Everything is built in
OUR coordinates (Y up, metres, floor at y = 0) through bcommon; every choice
comes from the random.Random passed in, so a seed always gives one scene.

A builder fills a Scene: Blender objects, the lights in our units (`lights`,
with the Blender terms in `lights_blender`), support surfaces (floor cells,
table tops, ground) and obstacles (AABBs) for the prop, and the camera's
allowed region and preferred heading."""
import math
import os

import bpy
import numpy as np

import bcommon
import materials_lib as ml
import units

WALL_T = 0.12


class Scene:
    def __init__(self, rnd):
        self.rnd = rnd
        self.kind = None
        self.indoor = True
        self.lights = []          # our units (scene coordinates)
        self.lights_blender = []  # the same lights in Blender's terms
        self.obstacles = []       # (lo, hi) AABBs, ours
        self.supports = []        # {"name", "y", "rect": (x0, x1, z0, z1), "support": floor|table|ground}
        self.cells = []           # floor cells (x0, x1, z0, z1): where the camera may stand
        self.camera_rect = None   # (x0, x1, z0, z1)
        self.heading = 0.0        # preferred camera yaw (deg), see units.camera_rotation
        self.sky = None           # {"type": ...} world sky; None: black world
        self.sun = None           # {"direction": ours, "elevation_deg", ...}
        self.surfaces = {}        # name -> material summary
        self.lamps = []           # shaded lamps: the bulb model behind their emitters
        self.portals = []         # Cycles light portals in window openings
        self.light_specs = []     # the Cycles light objects to make (finish_lights)
        self.choices = {}
        self.n = 0

    def name(self, base):
        self.n += 1
        return "%s_%03d" % (base, self.n)

    def mat(self, role, kind, **kw):
        m, s = ml.make(self.rnd, self.name(role), kind, **kw)
        self.surfaces[m.name] = dict(s, role=role)
        return m

    # --- lights --------------------------------------------------------------
    # Every local light is an emissive mesh visible to camera rays only (the
    # photo, the probe and the emitter mask see it) plus Cycles light objects of
    # the same radiance carrying its light along every other path: an AREA
    # rectangle for a quad or an opening disc (the square of its area: Cycles
    # samples rectangles by solid angle), a POINT light with a soft radius for
    # a sphere. The light objects are made by finish_lights(), which splits
    # rectangles into tiles so that next-event estimation picks lights roughly
    # by power: Cycles 3.4 picks emissive triangles by area whatever their
    # radiance, and light objects uniformly (docs/blender_world.md).
    def _record(self, name, blender, color, strength, what, **extra):
        self.lights_blender.append(dict({"object": name, "blender": blender,
                                         "color": [round(x, 4) for x in color], "strength": strength,
                                         "what": what}, **extra))

    def _rect_light(self, name, center, normal, axis_u, size_u, size_v, color, strength):
        self.light_specs.append({"name": name, "type": "rect", "center": np.asarray(center, float),
                                 "normal": np.asarray(normal, float), "axis_u": np.asarray(axis_u, float),
                                 "size": (float(size_u), float(size_v)), "color": list(color),
                                 "strength": float(strength), "record": self.lights_blender[-1]})

    def _point_light(self, name, center, radius, color, strength):
        self.light_specs.append({"name": name, "type": "point", "center": np.asarray(center, float),
                                 "radius": float(radius), "color": list(color), "strength": float(strength),
                                 "record": self.lights_blender[-1]})

    def area_emitter(self, corner, edge_u, edge_v, color, strength, what):
        name = self.name(what)
        mat = bcommon.emission_material(name + "_mat", color, strength)
        bcommon.camera_only(bcommon.quad(name, corner, edge_u, edge_v, mat))
        c = np.asarray(corner, float)
        u, v = np.asarray(edge_u, float), np.asarray(edge_v, float)
        self.lights.append({"type": "area", "intensity": units.mesh_emission_radiance(color, strength),
                            "position": (c + 0.5 * u + 0.5 * v).tolist(), "corner": c.tolist(),
                            "edge_u": u.tolist(), "edge_v": v.tolist(), "_what": what})
        self._record(name, "AREA light RECTANGLE (tiles) + camera-only emission quad", color, strength, what,
                     size_m=[float(np.linalg.norm(u)), float(np.linalg.norm(v))])
        self._rect_light(name, c + 0.5 * u + 0.5 * v, np.cross(u, v), u, np.linalg.norm(u), np.linalg.norm(v), color,
                         strength)

    def bulb(self, center, radius, color, strength, what):
        name = self.name(what)
        mat = bcommon.emission_material(name + "_mat", color, strength, one_sided=False)
        bcommon.camera_only(bcommon.uv_sphere(name, center, radius, mat, 24, 12))
        r_eff = units.uv_sphere_effective_radius(radius, 24, 12)
        self.lights.append({"type": "point", "intensity": units.mesh_emission_radiance(color, strength),
                            "position": [float(x) for x in center], "radius": r_eff, "_what": what})
        self._record(name, "POINT light (soft radius = effective radius) + camera-only emission UV sphere 24x12",
                     color, strength, what, radius_m=radius, effective_radius_m=r_eff)
        self._point_light(name, center, r_eff, color, strength)

    def disc_emitter(self, center, radius, facing_up, radiance, what, segments=32):
        """One-sided emissive disc (a regular polygon of `segments` sides) seen
        by the camera; its light is the square of the same centre, plane,
        facing, area and radiance, which is also ours (`area`)."""
        name = self.name(what)
        lum = max(float(units.luminance(radiance)), 1e-12)
        color = [float(c) / lum for c in radiance]
        bcommon.camera_only(bcommon.disc(name, center, radius, facing_up,
                                         bcommon.emission_material(name + "_mat", color, lum), segments))
        side = math.sqrt(0.5 * segments * radius ** 2 * math.sin(2 * math.pi / segments))
        c = np.asarray(center, float)
        eu, ev = (np.array([0, 0, side]), np.array([side, 0, 0])) if facing_up else \
            (np.array([side, 0, 0]), np.array([0, 0, side]))
        corner = c - 0.5 * eu - 0.5 * ev
        self.lights.append({"type": "area", "intensity": units.mesh_emission_radiance(color, lum),
                            "position": c.tolist(), "corner": corner.tolist(), "edge_u": eu.tolist(),
                            "edge_v": ev.tolist(), "_what": what})
        self._record(name, "AREA light SQUARE of equal area (tiles) + camera-only emission disc %d-gon "
                           "(one-sided, %s)" % (segments, "up" if facing_up else "down"), color, lum, what,
                     radius_m=radius, square_m=side, ours="area square of equal area and radiance")
        self._rect_light(name, c, (0, 1 if facing_up else -1, 0), (1, 0, 0), side, side, color, lum)

    def lampshade(self, kind, center_bottom, r_bot, r_top, height, bulb_y, bulb_r, bulb_radiance, kelvin,
                  transmittance, reflectance, opaque_material=None):
        """A bulb inside a shade (a frustum open at both ends), built as what
        leaves it (units.lampshade_emission): discs closing both openings carry
        the bulb's light through them (top facing up, bottom facing down), and
        a translucent shade glows outward with what it transmits (one-sided,
        plus its diffuse reflectance); an opaque shade (opaque_material) is not
        an emitter. No hidden bulb: every light is reachable by next-event
        estimation. The glowing shade's light is a sphere of the same power
        inside the shade (radius 0.45 x min(shade height, top diameter), so it
        stays clear of the stem and the openings); ours the same `point`."""
        x, yb, z = center_bottom
        slant = units.frustum_slant_area(r_bot, r_top, height)
        em = units.lampshade_emission(bulb_radiance, bulb_r, height - bulb_y, bulb_y, r_top, r_bot, slant,
                                      transmittance, reflectance)
        if opaque_material is None:
            name = self.name(kind + "_shade")
            rad = em["shade"]
            lum = max(float(units.luminance(rad)), 1e-12)
            color = [float(c) / lum for c in rad]
            refl = [max(0.0, float(r)) for r in reflectance]
            bcommon.camera_only(bcommon.frustum(
                name, (x, yb, z), r_bot, r_top, height,
                bcommon.emission_material(name + "_mat", color, lum, one_sided=True, reflectance=refl), 32))
            R = 0.45 * min(height, 2.0 * r_top)
            L_sphere = lum * slant / (4.0 * math.pi * R ** 2)  # pi A L = 4 pi^2 R^2 L'
            centre = [x, yb + height / 2, z]
            self.lights.append({"type": "point", "intensity": units.mesh_emission_radiance(color, L_sphere),
                                "position": centre, "radius": R, "_what": kind + "_shade"})
            self._record(name, "POINT light (a sphere of the shade's power) + camera-only emission frustum "
                               "(one-sided, outward, plus diffuse reflectance)", color, lum, kind + "_shade",
                         reflectance=[round(c, 4) for c in refl], sphere_radius_m=R, sphere_strength=L_sphere,
                         kelvin=kelvin, ours="point sphere of the shade's power")
            self._point_light(name, centre, R, color, L_sphere)
        else:
            bcommon.frustum(self.name(kind + "_shade"), (x, yb, z), r_bot, r_top, height, opaque_material, 32)
        self.disc_emitter((x, yb + height, z), r_top, True, em["top"], kind + "_top_opening")
        self.lights_blender[-1]["kelvin"] = kelvin
        self.disc_emitter((x, yb, z), r_bot, False, em["bottom"], kind + "_bottom_opening")
        self.lights_blender[-1]["kelvin"] = kelvin
        self.lamps.append({"kind": kind, "bulb_radiance": [float(c) for c in bulb_radiance], "bulb_radius_m": bulb_r,
                           "bulb_height_in_shade_m": bulb_y, "shade": {"r_bottom": r_bot, "r_top": r_top,
                                                                       "height": height, "bottom_y": yb},
                           "transmittance": [float(c) for c in transmittance],
                           "reflectance": [float(c) for c in reflectance], "glowing_shade": opaque_material is None,
                           "radiance_top": em["top"], "radiance_bottom": em["bottom"], "radiance_shade": em["shade"],
                           "budget": em["budget"]})

    def finish_lights(self, max_tiles=24):
        """Makes the Cycles light objects of light_specs. Cycles 3.4 picks a
        light object for next-event estimation uniformly, so each rectangle is
        split into n tiles (the same radiance: the same light) with n roughly
        proportional to its power: n = max(1, round(T w)), w its share of the
        power of all lights (the sun and the sky through windows included),
        T = min(max_tiles, 1 / the largest share of a light that cannot be
        split (a sphere, the sun, the sky)), so that no light gets much less
        than its share of the samples."""
        def lum(c):
            return float(units.luminance(c))
        powers = []
        for sp in self.light_specs:
            if sp["type"] == "rect":
                P = math.pi * sp["size"][0] * sp["size"][1] * sp["strength"] * lum(sp["color"])
            else:
                P = 4 * math.pi ** 2 * sp["radius"] ** 2 * sp["strength"] * lum(sp["color"])
            powers.append(P)
        outside = []  # what enters through the openings: the sky's (about half
        # the horizontal irradiance on a vertical opening), the sun's
        wins = self.choices.get("windows") or []
        a_win = sum(w["width_m"] * (w["top_m"] - w["sill_m"]) for w in wins)
        if self.indoor and a_win > 0 and self.sky is not None:
            outside.append(0.5 * self.sky.get("horizontal_irradiance", 0.0) * a_win)
            if self.sun is not None:
                outside.append(0.5 * self.sun.get("strength", 0.0) * lum(self.sun["color"]) * a_win)
        fixed = [P for P, sp in zip(powers, self.light_specs) if sp["type"] == "point"] + outside
        total = max(sum(powers) + sum(outside), 1e-12)
        T = min(max_tiles, total / max(fixed)) if fixed and max(fixed) > 0 else max_tiles
        self.choices["light_tiles_target"] = T
        for P, sp in zip(powers, self.light_specs):
            if sp["type"] == "point":
                bcommon.point_light(sp["name"] + "_light", sp["center"], sp["radius"], sp["color"], sp["strength"])
                sp["record"].update({"light_objects": 1, "light_power_w": P})
                continue
            n = max(1, int(round(T * P / total)))
            su, sv = sp["size"]
            nu = max(1, int(round(math.sqrt(n * su / sv))))
            nv = max(1, int(round(n / nu)))
            nrm = sp["normal"] / np.linalg.norm(sp["normal"])
            u = sp["axis_u"] - nrm * (sp["axis_u"] @ nrm)
            u /= np.linalg.norm(u)
            v = np.cross(nrm, u)
            for i in range(nu):
                for j in range(nv):
                    c = sp["center"] + u * su * ((i + 0.5) / nu - 0.5) + v * sv * ((j + 0.5) / nv - 0.5)
                    bcommon.area_light("%s_light_%d_%d" % (sp["name"], i, j), c, nrm, u, su / nu, sv / nv,
                                       sp["color"], sp["strength"])
            sp["record"].update({"light_objects": nu * nv, "tiles": [nu, nv], "light_power_w": P})

    def light_color(self, kelvin=None):
        if kelvin is None:
            kelvin = self.choices.get("kelvin") or 3000
        return units.blackbody_rgb(kelvin), kelvin

    def pick_kelvin(self):
        if self.choices.get("mixed_temperatures"):
            return self.rnd.choice([2700, 3000, 3500, 4000, 5000, 6500])
        return self.choices["kelvin"]

    # --- geometry ------------------------------------------------------------
    def solid(self, what, lo, hi, mat, obstacle=True):
        bcommon.box(self.name(what), lo, hi, mat)
        if obstacle:
            self.obstacles.append((tuple(lo), tuple(hi)))


# --- walls ---------------------------------------------------------------------
def wall(sc, a, b, outward, height, mat, openings=(), t=WALL_T):
    """Axis-aligned wall along floor segment a->b (x, z), outside the room
    (toward `outward`), floor to `height`; openings (s0, s1, y0, y1) along it."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = b - a
    L = float(np.linalg.norm(d))
    d /= L
    o = np.asarray(outward, float)
    spans = []
    cuts = sorted(openings)
    # vertical strips between openings, full height; above/below each opening
    s = 0.0
    for (s0, s1, y0, y1) in cuts:
        if s0 > s:
            spans.append((s, s0, 0.0, height))
        if y0 > 0:
            spans.append((s0, s1, 0.0, y0))
        if y1 < height:
            spans.append((s0, s1, y1, height))
        s = s1
    if s < L:
        spans.append((s, L, 0.0, height))
    for (s0, s1, y0, y1) in spans:
        p0 = a + d * s0
        p1 = a + d * s1 + o * t
        lo = (min(p0[0], p1[0]), y0, min(p0[1], p1[1]))
        hi = (max(p0[0], p1[0]), y1, max(p0[1], p1[1]))
        bcommon.box(sc.name("wall"), lo, hi, mat)


def polygon_room(sc, poly, height, wall_mat, openings_by_edge, skip_edges=(), ceiling=True, floor_mat=None,
                 ceil_mat=None, cells=None, slope=None):
    """poly: counter-clockwise (seen from above, x right, z down... any
    consistent order) axis-aligned polygon of (x, z). cells: rectangles
    covering it (floor/ceiling). slope: (axis 'x', x0, h0, x1, h1) sloped ceiling."""
    n = len(poly)
    P = np.asarray(poly, float)
    area2 = sum(P[i, 0] * P[(i + 1) % n, 1] - P[(i + 1) % n, 0] * P[i, 1] for i in range(n))
    sign = 1.0 if area2 > 0 else -1.0
    wall_h = height if slope is None else max(slope[2], slope[4]) + 0.15
    for i in range(n):
        if i in skip_edges:
            continue
        a, b = P[i], P[(i + 1) % n]
        d = (b - a) / np.linalg.norm(b - a)
        # outward normal of an edge of a polygon of orientation `sign`
        outward = np.array([d[1], -d[0]]) * sign
        wall(sc, a, b, outward, wall_h, wall_mat, openings_by_edge.get(i, ()))
    # convex corner posts
    for i in range(n):
        a, b, c = P[i - 1], P[i], P[(i + 1) % n]
        d1 = (b - a) / np.linalg.norm(b - a)
        d2 = (c - b) / np.linalg.norm(c - b)
        cross = d1[0] * d2[1] - d1[1] * d2[0]
        if cross * sign > 0:  # convex
            o1 = np.array([d1[1], -d1[0]]) * sign
            o2 = np.array([d2[1], -d2[0]]) * sign
            q = b + (o1 + o2) * WALL_T
            bcommon.box(sc.name("corner"), (min(b[0], q[0]), 0.0, min(b[1], q[1])), (max(b[0], q[0]), wall_h,
                                                                                          max(b[1], q[1])), wall_mat)
    for (x0, x1, z0, z1) in cells:
        e = WALL_T
        bcommon.box(sc.name("floor"), (x0 - e, -0.1, z0 - e), (x1 + e, 0.0, z1 + e), floor_mat)
        if ceiling and slope is None:
            bcommon.box(sc.name("ceiling"), (x0 - e, height, z0 - e), (x1 + e, height + 0.1, z1 + e), ceil_mat)
        sc.supports.append({"name": "floor", "y": 0.0, "rect": (x0, x1, z0, z1), "support": "floor"})
        sc.cells.append((x0, x1, z0, z1))
    if ceiling and slope is not None:
        _, sx0, h0, sx1, h1 = slope
        for (x0, x1, z0, z1) in cells:
            e = WALL_T + 0.05
            xa, xb = x0 - e, x1 + e

            def hy(x):
                return h0 + (x - sx0) * (h1 - h0) / (sx1 - sx0)
            v = [(xa, hy(xa), z0 - e), (xb, hy(xb), z0 - e), (xb, hy(xb), z1 + e), (xa, hy(xa), z1 + e)]
            v += [(p[0], p[1] + 0.1, p[2]) for p in v]
            f = [(0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 4, 0)]
            bcommon.mesh_object(sc.name("ceiling"), v, f, ceil_mat)


# --- furniture -------------------------------------------------------------------
def _free(sc, lo, hi, keep_out, margin=0.05):
    for (a, b) in sc.obstacles + keep_out:
        if (lo[0] < b[0] + margin and hi[0] > a[0] - margin and lo[2] < b[2] + margin and hi[2] > a[2] - margin
                and lo[1] < b[1] and hi[1] > a[1]):
            return False
    return True


def _inside_cells(sc, x0, x1, z0, z1):
    return any(x0 >= c[0] and x1 <= c[1] and z0 >= c[2] and z1 <= c[3] for c in sc.cells)


def place_footprint(sc, w, d, h, keep_out, against_wall, tries=40):
    """A free axis-aligned footprint (x0, x1, z0, z1) of w x d for something h tall."""
    rnd = sc.rnd
    for _ in range(tries):
        cell = rnd.choice(sc.cells)
        ww, dd = (w, d) if rnd.random() < 0.5 else (d, w)
        if cell[1] - cell[0] < ww + 0.1 or cell[3] - cell[2] < dd + 0.1:
            continue
        if against_wall:
            side = rnd.randrange(4)
            x = rnd.uniform(cell[0] + 0.02, cell[1] - ww - 0.02)
            z = rnd.uniform(cell[2] + 0.02, cell[3] - dd - 0.02)
            if side == 0:
                x = cell[0] + 0.02
            elif side == 1:
                x = cell[1] - ww - 0.02
            elif side == 2:
                z = cell[2] + 0.02
            else:
                z = cell[3] - dd - 0.02
        else:
            x = rnd.uniform(cell[0] + 0.3, cell[1] - ww - 0.3) if cell[1] - cell[0] > ww + 0.7 else None
            z = rnd.uniform(cell[2] + 0.3, cell[3] - dd - 0.3) if cell[3] - cell[2] > dd + 0.7 else None
            if x is None or z is None:
                continue
        lo, hi = (x, 0.0, z), (x + ww, h, z + dd)
        if _inside_cells(sc, x, x + ww, z, z + dd) and _free(sc, lo, hi, keep_out):
            return (x, x + ww, z, z + dd)
    return None


def furniture(sc, keep_out, count):
    rnd = sc.rnd
    made = []
    kinds = ["sofa", "table", "shelf", "bed", "box", "box", "table", "cabinet"]
    for _ in range(count):
        k = rnd.choice(kinds)
        if k == "sofa":
            fp = place_footprint(sc, rnd.uniform(1.6, 2.2), rnd.uniform(0.8, 0.95), 0.85, keep_out, True)
            if not fp:
                continue
            m = sc.mat("sofa", rnd.choice(["paint", "carpet", "stripes"]), glossy=False)
            x0, x1, z0, z1 = fp
            sc.solid("sofa", (x0, 0, z0), (x1, 0.42, z1), m)
            # back along the longer side nearest a wall: keep simple, back along the far x or z edge
            if x1 - x0 > z1 - z0:
                sc.solid("sofa_back", (x0, 0.42, z0), (x1, 0.85, z0 + 0.2), m)
                sc.solid("sofa_arm", (x0, 0.42, z0), (x0 + 0.18, 0.62, z1), m)
                sc.solid("sofa_arm", (x1 - 0.18, 0.42, z0), (x1, 0.62, z1), m)
            else:
                sc.solid("sofa_back", (x0, 0.42, z0), (x0 + 0.2, 0.85, z1), m)
                sc.solid("sofa_arm", (x0, 0.42, z0), (x1, 0.62, z0 + 0.18), m)
                sc.solid("sofa_arm", (x0, 0.42, z1 - 0.18), (x1, 0.62, z1), m)
        elif k == "table":
            h = rnd.uniform(0.7, 0.78) if rnd.random() < 0.7 else rnd.uniform(0.4, 0.5)
            fp = place_footprint(sc, rnd.uniform(0.8, 1.6), rnd.uniform(0.6, 0.9), h, keep_out, False)
            if not fp:
                continue
            m = sc.mat("table", rnd.choice(["wood", "paint", "wood"]))
            x0, x1, z0, z1 = fp
            bcommon.box(sc.name("table_top"), (x0, h - 0.04, z0), (x1, h, z1), m)
            for (lx, lz) in ((x0 + 0.03, z0 + 0.03), (x1 - 0.08, z0 + 0.03), (x0 + 0.03, z1 - 0.08),
                             (x1 - 0.08, z1 - 0.08)):
                bcommon.box(sc.name("table_leg"), (lx, 0, lz), (lx + 0.05, h - 0.04, lz + 0.05), m)
            sc.obstacles.append(((x0, 0, z0), (x1, h, z1)))
            sc.supports.append({"name": "table", "y": h, "rect": (x0 + 0.05, x1 - 0.05, z0 + 0.05, z1 - 0.05),
                                "support": "table"})
            made.append(("table", fp, h))
        elif k in ("shelf", "cabinet"):
            h = rnd.uniform(1.4, 2.0) if k == "shelf" else rnd.uniform(0.8, 1.0)
            fp = place_footprint(sc, rnd.uniform(0.6, 1.4), rnd.uniform(0.3, 0.45), h, keep_out, True)
            if not fp:
                continue
            m = sc.mat(k, rnd.choice(["wood", "paint"]))
            x0, x1, z0, z1 = fp
            if k == "cabinet":
                sc.solid("cabinet", (x0, 0, z0), (x1, h, z1), m)
            else:
                t = 0.025
                for (a, b) in (((x0, 0, z0), (x0 + t, h, z1)), ((x1 - t, 0, z0), (x1, h, z1))):
                    bcommon.box(sc.name("shelf_side"), a, b, m)
                n = rnd.randint(3, 5)
                for i in range(n + 1):
                    y = min(i * h / n, h - t)
                    bcommon.box(sc.name("shelf_board"), (x0 + t, y, z0), (x1 - t, y + t, z1), m)
                    if i < n and rnd.random() < 0.7:  # books / boxes
                        bx = x0 + t + rnd.uniform(0, 0.3) * (x1 - x0)
                        bw = rnd.uniform(0.1, 0.35) * (x1 - x0)
                        bh = rnd.uniform(0.12, 0.8) * (h / n - t)
                        bcommon.box(sc.name("book"), (bx, y + t, z0 + 0.02), (min(bx + bw, x1 - t), y + t + bh,
                                                                                z1 - 0.03),
                                    sc.mat("book", "paint", glossy=False))
                sc.obstacles.append(((x0, 0, z0), (x1, h, z1)))
        elif k == "bed":
            fp = place_footprint(sc, rnd.uniform(1.4, 1.8), rnd.uniform(2.0, 2.1), 0.6, keep_out, True)
            if not fp:
                continue
            x0, x1, z0, z1 = fp
            sc.solid("bed_base", (x0, 0, z0), (x1, 0.3, z1), sc.mat("bed", "wood"))
            bcommon.box(sc.name("mattress"), (x0 + 0.03, 0.3, z0 + 0.03), (x1 - 0.03, 0.5, z1 - 0.03),
                        sc.mat("linen", rnd.choice(["paint", "stripes", "checker"]), glossy=False))
            sc.obstacles.append(((x0, 0, z0), (x1, 0.95, z1)))
        else:
            n = rnd.randint(1, 3)
            s = rnd.uniform(0.25, 0.6)
            fp = place_footprint(sc, s, s * rnd.uniform(0.7, 1.3), s * n, keep_out, rnd.random() < 0.5)
            if not fp:
                continue
            x0, x1, z0, z1 = fp
            y = 0.0
            for i in range(n):
                hh = rnd.uniform(0.2, 0.5)
                sh = rnd.uniform(0.0, 0.05)
                bcommon.box(sc.name("box"), (x0 + sh, y, z0 + sh), (x1 - sh, y + hh, z1 - sh),
                            sc.mat("box", rnd.choice(["paint", "paint", "checker"])))
                y += hh
            sc.obstacles.append(((x0, 0, z0), (x1, y, z1)))
    return made


# --- lights in rooms ---------------------------------------------------------------
def lamp_on(sc, base, height, kind, color, strength, kelvin):
    """Floor/table lamp: stem, a fabric shade glowing with the light it
    transmits, discs closing its openings with the bulb's light that leaves
    through them (Scene.lampshade)."""
    rnd = sc.rnd
    x, y0, z = base
    metal = bcommon.metal_material(sc.name("lamp_metal"), [0.6, 0.55, 0.45], 0.3)
    r_bot, r_top, sh = rnd.uniform(0.16, 0.24), rnd.uniform(0.1, 0.16), rnd.uniform(0.2, 0.3)
    if kind == "table_lamp":
        r_bot, r_top, sh = r_bot * 0.7, r_top * 0.7, sh * 0.8
    bcommon.cylinder(sc.name(kind + "_base"), (x, y0, z), 0.12 if kind == "floor_lamp" else 0.07, 0.03, metal)
    # the stem ends at the shade's bottom opening (inside, the shade is closed)
    bcommon.cylinder(sc.name(kind + "_stem"), (x, y0 + 0.03, z), 0.012, height - sh - 0.03, metal)
    shade_c = rnd.choice([[0.9, 0.85, 0.7], [0.85, 0.85, 0.85], [0.8, 0.6, 0.4], [0.7, 0.75, 0.8]])
    tau = rnd.uniform(0.1, 0.25)  # the fabric: transmits tau * colour, reflects (1 - tau) * colour
    # the bulb it stands for: radius 5 cm, 0.55 of the way up the shade
    sc.lampshade(kind, (x, y0 + height - sh, z), r_bot, r_top, sh, 0.55 * sh, 0.05,
                 [c * strength * 0.36 for c in color], kelvin,
                 transmittance=[tau * c for c in shade_c], reflectance=[(1 - tau) * c for c in shade_c])
    sc.obstacles.append(((x - r_bot, y0, z - r_bot), (x + r_bot, y0 + height, z + r_bot)))


def ceiling_lights(sc, cells, ceil_y, n_max, style, strength_scale=1.0):
    rnd = sc.rnd
    for cell in cells:
        x0, x1, z0, z1 = cell
        nx = max(1, min(n_max, int((x1 - x0) / 2.2)))
        nz = max(1, min(n_max, int((z1 - z0) / 2.2)))
        for i in range(nx):
            for j in range(nz):
                if rnd.random() < 0.15 and nx * nz > 1:
                    continue
                cx = x0 + (i + 0.5) * (x1 - x0) / nx + rnd.uniform(-0.2, 0.2)
                cz = z0 + (j + 0.5) * (z1 - z0) / nz + rnd.uniform(-0.2, 0.2)
                k = sc.pick_kelvin()
                col, _ = sc.light_color(k)
                y = ceil_y(cx) if callable(ceil_y) else ceil_y
                if style == "panel":
                    w, d = rnd.choice([(0.6, 0.6), (1.2, 0.3), (0.6, 1.2), (0.4, 0.4)])
                    L = rnd.uniform(3.0, 10.0) * strength_scale
                    sc.area_emitter((cx - w / 2, y - 0.002, cz - d / 2), (w, 0, 0), (0, 0, d), col, L, "ceiling_panel")
                elif style == "spot":
                    s = rnd.uniform(0.08, 0.14)
                    for (ox, oz) in ((-0.4, 0), (0.4, 0)) if rnd.random() < 0.5 else ((0, 0),):
                        sc.area_emitter((cx + ox - s / 2, y - 0.002, cz + oz - s / 2), (s, 0, 0), (0, 0, s), col,
                                        rnd.uniform(20.0, 45.0) * strength_scale, "recessed_spot")
                elif style in ("pendant", "bare_bulb"):
                    drop = rnd.uniform(0.5, 1.0)
                    yb = y - drop
                    bcommon.cylinder(sc.name("cable"), (cx, yb, cz), 0.004, drop,
                                     bcommon.diffuse_material(sc.name("cable_mat"), [0.05, 0.05, 0.05]), 8)
                    L = rnd.uniform(25.0, 60.0) * strength_scale
                    if style == "pendant":
                        # an opaque shade (plastic, F0 0.05): what leaves it is the
                        # light through its two openings (Scene.lampshade)
                        rb = rnd.uniform(0.15, 0.25)
                        pc = ml.random_color(rnd, "paint")
                        shade = bcommon.plastic_material(sc.name("pendant_shade"), pc, 0.05, 0.1)
                        sc.lampshade("pendant", (cx, yb - 0.12, cz), rb, 0.05, 0.2, 0.05, 0.04,
                                     [c * L * 0.56 for c in col], k, transmittance=[0.0, 0.0, 0.0],
                                     reflectance=[0.05 + 0.95 * c for c in pc], opaque_material=shade)
                    else:
                        sc.bulb((cx, yb - 0.045, cz), 0.04, col, L * 0.56, "bare_bulb")
                        sc.lights_blender[-1]["kelvin"] = k
                if style not in ("pendant", "bare_bulb"):
                    sc.lights_blender[-1]["kelvin"] = k


def overcast_world(sc, color, strength):
    """CIE overcast sky: L(theta) = L_z (1 + 2 cos theta) / 3 above the
    horizon, a dim ground colour below."""
    nt = bpy.context.scene.world.node_tree
    nt.nodes.clear()
    tc = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(tc.outputs["Generated"], sep.inputs[0])
    mx = nt.nodes.new("ShaderNodeMath")
    mx.operation = "MAXIMUM"
    mx.inputs[1].default_value = 0.0
    nt.links.new(sep.outputs["Z"], mx.inputs[0])
    ma = nt.nodes.new("ShaderNodeMath")
    ma.operation = "MULTIPLY_ADD"
    ma.inputs[1].default_value = 2.0 / 3.0
    ma.inputs[2].default_value = 1.0 / 3.0
    nt.links.new(mx.outputs[0], ma.inputs[0])
    # below the horizon: 0.3 of the horizon radiance
    gt = nt.nodes.new("ShaderNodeMath")
    gt.operation = "GREATER_THAN"
    gt.inputs[1].default_value = 0.0
    nt.links.new(sep.outputs["Z"], gt.inputs[0])
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "FLOAT"
    mix.inputs["A"].default_value = 0.1
    nt.links.new(gt.outputs[0], mix.inputs["Factor"])
    nt.links.new(ma.outputs[0], mix.inputs["B"])
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Color"].default_value = tuple(color) + (1.0,)
    nt.links.new(mix.outputs["Result"], bg.inputs["Strength"])
    scale = nt.nodes.new("ShaderNodeMath")
    scale.operation = "MULTIPLY"
    scale.inputs[1].default_value = strength
    nt.links.new(mix.outputs["Result"], scale.inputs[0])
    nt.links.new(scale.outputs[0], bg.inputs["Strength"])
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(bg.outputs[0], out.inputs[0])
    sc.sky = {"type": "cie_overcast", "color": [round(c, 4) for c in color], "node": bg}


def clear_sky_world(sc, sun_dir_ours, model):
    """Nishita or Hosek-Wilkie sky, no sun disc (the sun is a Sun light)."""
    rnd = sc.rnd
    nt = bpy.context.scene.world.node_tree
    nt.nodes.clear()
    sky = nt.nodes.new("ShaderNodeTexSky")
    d = units.to_blender(sun_dir_ours)
    elev = math.asin(max(-1.0, min(1.0, d[2])))
    rot = math.atan2(d[0], d[1])  # Blender's sun_rotation: angle from +Y toward +X
    info = {"type": model.lower(), "sun_elevation_deg": math.degrees(elev)}
    if model == "NISHITA":
        sky.sky_type = "NISHITA"
        sky.sun_disc = False
        sky.sun_elevation = elev
        sky.sun_rotation = rot % (2 * math.pi)
        sky.altitude = rnd.uniform(0, 500)
        sky.air_density = rnd.uniform(0.8, 2.0)
        sky.dust_density = rnd.uniform(0.5, 4.0)
        sky.ozone_density = rnd.uniform(0.8, 1.5)
        info.update({"altitude": sky.altitude, "air": sky.air_density, "dust": sky.dust_density,
                     "ozone": sky.ozone_density, "sun_rotation_deg": math.degrees(sky.sun_rotation)})
    else:
        sky.sky_type = "HOSEK_WILKIE"
        sky.sun_direction = d
        sky.turbidity = rnd.uniform(2.0, 6.0)
        sky.ground_albedo = rnd.uniform(0.1, 0.4)
        info.update({"turbidity": sky.turbidity, "ground_albedo": sky.ground_albedo})
    bg = nt.nodes.new("ShaderNodeBackground")
    nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(bg.outputs[0], out.inputs[0])
    info["node"] = bg
    sc.sky = info


def add_sun(sc, direction_ours, strength, angle_deg_diameter, kelvin=5500):
    col = units.blackbody_rgb(kelvin)
    lamp = bpy.data.lights.new("sun", "SUN")
    lamp.energy = strength
    lamp.color = col
    lamp.angle = math.radians(angle_deg_diameter)
    obj = bpy.data.objects.new("sun", lamp)
    bpy.context.scene.collection.objects.link(obj)
    d = np.asarray(units.to_blender(direction_ours))
    # a sun shines along its local -Z: point local +Z toward the sun
    from mathutils import Vector
    obj.rotation_euler = Vector(d.tolist()).to_track_quat("Z", "Y").to_euler()
    sc.sun = {"direction": list(np.asarray(direction_ours) / np.linalg.norm(direction_ours)), "object": obj,
              "color": col, "kelvin": kelvin, "angle_diameter_deg": angle_deg_diameter}
    return obj


def set_sun_strength(sc, strength):
    sc.sun["object"].data.energy = strength
    sc.sun["strength"] = strength


# --- indoor kinds ---------------------------------------------------------------------
def build_indoor(sc):
    rnd = sc.rnd
    kind = rnd.choice(["room", "room", "l_room", "corridor", "sloped", "doorway"])
    sc.kind = kind
    sc.indoor = True
    H = rnd.uniform(2.4, 3.1)
    wall_mat = sc.mat("walls", rnd.choice(["paint", "paint", "paint", "stripes", "tiles", "brick"]))
    floor_mat = sc.mat("floor", rnd.choice(["wood", "tiles", "carpet", "checker", "paint", "concrete"]))
    ceil_mat = sc.mat("ceiling", "paint", base=[rnd.uniform(0.7, 0.9)] * 3, glossy=False)
    openings = {}
    slope = None
    if kind in ("room", "sloped", "doorway"):
        W, D = rnd.uniform(3.5, 7.0), rnd.uniform(3.5, 7.0)
        poly = [(0, 0), (W, 0), (W, D), (0, D)]
        cells = [(0, W, 0, D)]
    elif kind == "l_room":
        W, D = rnd.uniform(4.5, 7.5), rnd.uniform(3.0, 4.5)
        b, e = rnd.uniform(2.0, W - 1.5), rnd.uniform(2.0, 4.0)
        poly = [(0, 0), (W, 0), (W, D), (b, D), (b, D + e), (0, D + e)]
        cells = [(0, W, 0, D), (0, b, D, D + e)]
    else:  # corridor
        W, D = rnd.uniform(1.6, 2.4), rnd.uniform(8.0, 16.0)
        poly = [(0, 0), (W, 0), (W, D), (0, D)]
        cells = [(0, W, 0, D)]
    if kind == "sloped":
        h_low, h_high = rnd.uniform(1.9, 2.3), rnd.uniform(3.0, 3.8)
        if rnd.random() < 0.5:
            h_low, h_high = h_high, h_low
        slope = ("x", 0.0, h_low, W, h_high)
        H = max(h_low, h_high)
    # light plan
    plans = ["ceiling", "ceiling", "lamps", "window_sun", "window_overcast", "offscreen", "dim", "mixed"]
    plan = rnd.choice(plans)
    # a study of one kind of light (make_blender_world.sh --indoor-plan): the
    # draw above still happens, so the seed's other choices stay the same
    forced = os.environ.get("PROPCAM_WORLD_INDOOR_PLAN", "")
    if forced:
        if forced not in plans:
            raise ValueError("unknown indoor plan %r (one of %s)" % (forced, ", ".join(sorted(set(plans)))))
        plan = forced
    if kind == "corridor" and plan in ("lamps",):
        plan = "ceiling"
    sc.choices.update({"height_m": H, "plan": plan, "size_m": [W, D], "kelvin": rnd.choice([2700, 3000, 4000, 5000]),
                       "mixed_temperatures": plan == "mixed" or rnd.random() < 0.25})
    windows = []
    if plan in ("window_sun", "window_overcast") or (plan in ("ceiling", "mixed") and rnd.random() < 0.4):
        # windows on one or two edges of the polygon (not the shared one of a doorway)
        edges = list(range(len(poly)))
        rnd.shuffle(edges)
        for ei in edges[:rnd.randint(1, 2)]:
            a, b = np.asarray(poly[ei], float), np.asarray(poly[(ei + 1) % len(poly)], float)
            L = float(np.linalg.norm(b - a))
            if L < 1.6:
                continue
            ww = rnd.uniform(0.8, min(2.2, L - 0.6))
            s0 = rnd.uniform(0.3, L - ww - 0.3)
            sill = rnd.uniform(0.4, 1.0)
            top = min(rnd.uniform(1.9, 2.3), (min(slope[2], slope[4]) if slope else H) - 0.15)
            openings.setdefault(ei, []).append((s0, s0 + ww, sill, top))
            windows.append((ei, a, b, s0, ww, sill, top))
    skip = ()
    if kind == "doorway":
        # a second room beyond the +x wall (edge 1: (W,0)->(W,D)), a door in it
        dw = rnd.uniform(0.8, 1.3)
        s0 = rnd.uniform(0.3, D - dw - 0.3)
        openings.setdefault(1, []).append((s0, s0 + dw, 0.0, min(2.1, H - 0.2)))
        W2, D2 = rnd.uniform(2.5, 4.5), rnd.uniform(3.0, 5.0)
        z2 = s0 + dw / 2 - D2 / 2
        x2 = W + WALL_T
        poly2 = [(x2, z2), (x2 + W2, z2), (x2 + W2, z2 + D2), (x2, z2 + D2)]
        sc.choices["door"] = {"width_m": dw, "other_room_m": [W2, D2]}
        other_wall = sc.mat("walls2", "paint")
        # room 2's wall toward room 1 is skipped where room 1's wall stands (edge 3: (x2, z2+D2)->(x2, z2))
        # but room 2 may be wider than room 1: build its edge-3 wall outside room 1's extent only
        # its floor and ceiling start beyond room 1's wall (no coplanar overlap under the door)
        polygon_room(sc, poly2, H, other_wall, {}, skip_edges=(3,), floor_mat=floor_mat, ceil_mat=ceil_mat,
                     cells=[(x2 + WALL_T, x2 + W2, z2, z2 + D2)])
        for (za, zb) in ((z2 - WALL_T, 0.0 - WALL_T), (D + WALL_T, z2 + D2 + WALL_T)):
            if zb > za + 1e-3:
                bcommon.box(sc.name("wall"), (W, 0, za), (x2, H, zb), other_wall)
        sc.cells.pop()  # the camera and the prop stay in room 1
        sc.supports.pop()
        col, _ = sc.light_color(sc.pick_kelvin())
        # big, moderate panels: room 1 sees the next room's light mostly by its
        # bounces, so a large source keeps the paths through the door smooth
        if rnd.random() < 0.5:
            sc.area_emitter((x2 + W2 / 2 - 0.6, H - 0.002, z2 + D2 / 2 - 0.6), (1.2, 0, 0), (0, 0, 1.2), col,
                            rnd.uniform(1.5, 4.0), "next_room_panel")
        else:
            L2 = min(D2 - 1.0, 2.4)
            sc.area_emitter((x2 + W2 / 2 - 0.3, H - 0.002, z2 + D2 / 2 - L2 / 2), (0.6, 0, 0), (0, 0, L2), col,
                            rnd.uniform(2.0, 6.0), "next_room_strip")
    polygon_room(sc, poly, H, wall_mat, openings, skip_edges=skip, floor_mat=floor_mat, ceil_mat=ceil_mat,
                 cells=cells, slope=slope)
    if windows:
        # light portals filling the openings at the wall's outer face: Cycles
        # samples the world through them (they emit nothing themselves)
        sign = 1.0 if _orient(poly) > 0 else -1.0
        for (ei, a, b, s0, ww, sill, top) in windows:
            d = (b - a) / np.linalg.norm(b - a)
            outward = np.array([d[1], -d[0]]) * sign
            c2 = a + d * (s0 + ww / 2) + outward * WALL_T
            center = (float(c2[0]), (sill + top) / 2, float(c2[1]))
            name = sc.name("portal")
            bcommon.portal(name, center, (-outward[0], 0.0, -outward[1]), ww, top - sill)
            sc.portals.append({"object": name, "center": list(center), "inward": [-outward[0], 0.0, -outward[1]],
                               "size_m": [ww, top - sill], "blender": "AREA light, is_portal"})
        # the outside: ground below the floor level, the sky
        g = sc.mat("outside_ground", rnd.choice(["concrete", "asphalt", "paint"]), glossy=False)
        nt = g.node_tree
        bcommon._aov(nt, 1.0)
        bcommon.box(sc.name("outside_ground"), (-60, -0.6, -60), (60, -0.5, 60), g)
    # camera region: room 1's first cell, away from the walls
    c0 = cells[0]
    sc.camera_rect = (c0[0] + 0.4, c0[1] - 0.4, c0[2] + 0.4, c0[3] - 0.4)
    if kind == "corridor":
        sc.camera_rect = (c0[0] + 0.4, c0[1] - 0.4, c0[2] + 0.3, c0[2] + 1.2)
    # camera position first (furniture keeps clear of it)
    cx = rnd.uniform(sc.camera_rect[0], sc.camera_rect[1])
    cz = rnd.uniform(sc.camera_rect[2], sc.camera_rect[3])
    sc.camera_xz = (cx, cz)
    # head toward the farthest part of the floor
    centers = [((c[0] + c[1]) / 2, (c[2] + c[3]) / 2) for c in cells]
    far = max(centers + [(c[0], c[2]) for c in cells] + [(c[1], c[3]) for c in cells] +
              [(c[0], c[3]) for c in cells] + [(c[1], c[2]) for c in cells],
              key=lambda p: (p[0] - cx) ** 2 + (p[1] - cz) ** 2)
    tx, tz = (far[0] + centers[0][0]) / 2, (far[1] + centers[0][1]) / 2
    if (tx - cx) ** 2 + (tz - cz) ** 2 < 1.0:
        tx, tz = far
    sc.heading = math.degrees(math.atan2(-(tx - cx), -(tz - cz)))
    keep_out = [((cx - 0.6, 0, cz - 0.6), (cx + 0.6, 3, cz + 0.6))]
    furniture(sc, keep_out, rnd.randint(2, 6) if kind != "corridor" else rnd.randint(0, 2))
    # lights
    ceil = H if slope is None else (lambda x: slope[2] + (x - slope[1]) * (slope[4] - slope[2]) / (slope[3] - slope[1]))
    if plan in ("ceiling", "mixed"):
        style = rnd.choice(["panel", "panel", "spot", "pendant", "bare_bulb"])
        if slope is not None and style in ("pendant", "bare_bulb"):
            style = "panel"
        if slope is not None:
            # panels parallel to the slope
            for cell in cells:
                x0, x1, z0, z1 = cell
                for _ in range(rnd.randint(1, 2)):
                    px = rnd.uniform(x0 + 0.5, x1 - 1.0)
                    pz = rnd.uniform(z0 + 0.5, z1 - 1.0)
                    w, d = 0.6, 0.6
                    ya, yb = ceil(px), ceil(px + w)
                    col, _ = sc.light_color(sc.pick_kelvin())
                    # corner at (px, ya), edge_u along the slope, edge_v along z: u x v must point down
                    sc.area_emitter((px, ya - 0.003, pz), (w, yb - ya, 0), (0, 0, d), col, rnd.uniform(3, 10),
                                    "sloped_panel")
        else:
            ceiling_lights(sc, cells, H, 2, style)
        sc.choices["ceiling_style"] = style
    if plan in ("lamps", "mixed", "dim") or (plan == "ceiling" and rnd.random() < 0.3):
        n = 1 if plan == "dim" else rnd.randint(1, 2)
        for _ in range(n):
            tables = [s for s in sc.supports if s["support"] == "table"]
            k = sc.pick_kelvin()
            col, _ = sc.light_color(k)
            L = rnd.uniform(30, 80) * (0.5 if plan == "dim" else 1.0)
            if tables and rnd.random() < 0.5:
                t = rnd.choice(tables)
                x0, x1, z0, z1 = t["rect"]
                lamp_on(sc, ((x0 + x1) / 2 + rnd.uniform(-0.2, 0.2) * (x1 - x0), t["y"], (z0 + z1) / 2), 0.55,
                        "table_lamp", col, L, k)
                t["rect"] = (x0, x1, z0, z1)
                t["has_lamp"] = True
            else:
                fp = place_footprint(sc, 0.45, 0.45, 1.6, keep_out, True)
                if fp:
                    lamp_on(sc, ((fp[0] + fp[1]) / 2, 0.0, (fp[2] + fp[3]) / 2), rnd.uniform(1.4, 1.7), "floor_lamp",
                            col, L, k)
                elif plan == "dim":
                    ceiling_lights(sc, cells[:1], H if slope is None else ceil, 1, "bare_bulb", 0.5)
    if plan == "offscreen":
        # lights behind and beside the camera only: panels on the ceiling near the camera's back wall
        hx = -math.sin(math.radians(sc.heading))
        hz = -math.cos(math.radians(sc.heading))
        for _ in range(rnd.randint(1, 2)):
            back = rnd.uniform(0.3, 1.2)
            px, pz = cx - hx * back + rnd.uniform(-0.6, 0.6), cz - hz * back + rnd.uniform(-0.6, 0.6)
            px = min(max(px, cells[0][0] + 0.4), cells[0][1] - 0.4)
            pz = min(max(pz, cells[0][2] + 0.4), cells[0][3] - 0.4)
            col, _ = sc.light_color(sc.pick_kelvin())
            y = ceil(px) if callable(ceil) else ceil
            if slope is None:
                sc.area_emitter((px - 0.3, y - 0.002, pz - 0.3), (0.6, 0, 0), (0, 0, 0.6), col, rnd.uniform(5, 15),
                                "offscreen_panel")
            else:
                sc.bulb((px, y - 0.3, pz), 0.04, col, rnd.uniform(30, 60), "offscreen_bulb")
        sc.choices["offscreen"] = True
    if plan == "dim" and not sc.lights:
        ceiling_lights(sc, cells[:1], H if slope is None else ceil, 1, "bare_bulb", 0.5)
    if windows:
        sky_kind = "overcast" if plan == "window_overcast" or (plan != "window_sun" and rnd.random() < 0.5) else "clear"
        sc.choices["window_sky"] = sky_kind
        sc.choices["windows"] = [{"edge": w[0], "width_m": w[4], "sill_m": w[5], "top_m": w[6]} for w in windows]
        if sky_kind == "overcast":
            overcast_world(sc, [0.95, 0.97, 1.0], 1.0)
        else:
            # the sun through a window onto the floor: aim from a floor point through the window's centre
            ei, a, b, s0, ww, sill, top = windows[0]
            d = (b - a) / np.linalg.norm(b - a)
            wc = a + d * (s0 + ww / 2)
            n_in = -np.array([d[1], -d[0]]) * (1.0 if _orient(poly) > 0 else -1.0)
            wy = (sill + top) / 2
            elev = math.radians(rnd.uniform(20, 55))
            side = rnd.uniform(-0.6, 0.6)
            horiz = n_in * math.cos(side) + np.array([-n_in[1], n_in[0]]) * math.sin(side)
            sun_dir = np.array([-horiz[0] * math.cos(elev), math.sin(elev), -horiz[1] * math.cos(elev)])
            model = rnd.choice(["NISHITA", "HOSEK_WILKIE"])
            sun_angle, sun_k = rnd.uniform(0.5, 2.0), rnd.choice([5000, 5500, 6000])
            if plan == "window_sun":
                clear_sky_world(sc, sun_dir, model)
                add_sun(sc, sun_dir, 1.0, sun_angle, sun_k)
            else:
                # windows of the other plans: a clear twilight sky, the sun 1-5 deg
                # below the horizon (a sun patch lighting a room by its bounce is
                # window_sun's; in a room lit by its own lights it would outshine
                # them by its bounce alone, the noisiest light there is)
                tw = -math.radians(1.0 + 4.0 * (math.degrees(elev) - 20.0) / 35.0)
                sun_dir = np.array([-horiz[0] * math.cos(tw), math.sin(tw), -horiz[1] * math.cos(tw)])
                clear_sky_world(sc, sun_dir, "NISHITA")
                sc.choices["window_sky"] = "twilight"
        target = rnd.uniform(4.0, 20.0) if plan.startswith("window") else rnd.uniform(2, 8)
        if sc.choices["window_sky"] == "twilight":
            target *= 0.15  # dusk: the room's own lights dominate
        sc.choices["sky_target_radiance"] = target
        sc.choices["sun_ratio"] = rnd.uniform(3.0, 8.0)
    if not sc.lights and sc.sky is None:
        ceiling_lights(sc, cells, H if slope is None else ceil, 2, "panel")
    return sc


def _orient(poly):
    P = np.asarray(poly, float)
    n = len(P)
    return sum(P[i, 0] * P[(i + 1) % n, 1] - P[(i + 1) % n, 0] * P[i, 1] for i in range(n))


# --- outdoor kinds ---------------------------------------------------------------------
def facade(sc, x0, x1, z0, z1, height, mat, window_mat, face):
    """A building block with window insets on its face toward `face` ('+x','-x','+z','-z')."""
    rnd = sc.rnd
    sc.solid("building", (x0, 0, z0), (x1, height, z1), mat)
    floors = int(height / 3.0)
    along = (x0, x1) if face in ("+z", "-z") else (z0, z1)
    n = max(1, int((along[1] - along[0]) / rnd.uniform(2.0, 3.5)))
    ww = rnd.uniform(0.8, 1.4)
    for f in range(floors):
        y0 = f * 3.0 + (1.0 if f > 0 else 0.9)
        y1 = y0 + (1.5 if f > 0 else 1.3)
        if y1 > height - 0.3:
            break
        for i in range(n):
            c = along[0] + (i + 0.5) * (along[1] - along[0]) / n
            if face == "+z":
                bcommon.box(sc.name("window"), (c - ww / 2, y0, z1), (c + ww / 2, y1, z1 + 0.03), window_mat)
            elif face == "-z":
                bcommon.box(sc.name("window"), (c - ww / 2, y0, z0 - 0.03), (c + ww / 2, y1, z0), window_mat)
            elif face == "+x":
                bcommon.box(sc.name("window"), (x1, y0, c - ww / 2), (x1 + 0.03, y1, c + ww / 2), window_mat)
            else:
                bcommon.box(sc.name("window"), (x0 - 0.03, y0, c - ww / 2), (x0, y1, c + ww / 2), window_mat)


def build_outdoor(sc):
    rnd = sc.rnd
    kind = rnd.choice(["street", "courtyard", "plaza"])
    sc.kind = kind
    sc.indoor = False
    ground = sc.mat("ground", rnd.choice(["asphalt", "concrete", "tiles", "brick"]), glossy=False)
    win = bcommon.plastic_material(sc.name("window_glass"), [0.02, 0.025, 0.03], 0.04, 0.01)
    facade_kinds = ["paint", "brick", "concrete", "tiles", "stripes"]
    R = 80.0
    bcommon.box(sc.name("ground"), (-R, -0.2, -R), (R, 0.0, R), ground)
    if kind == "street":
        w = rnd.uniform(8.0, 16.0)
        L = rnd.uniform(40, 70)
        for side in (-1, 1):
            x = 0.0
            z = -L / 2
            while z < L / 2:
                bl = rnd.uniform(6, 15)
                h = rnd.uniform(6, 20)
                dep = rnd.uniform(8, 12)
                m = sc.mat("facade", rnd.choice(facade_kinds))
                if side < 0:
                    facade(sc, -w / 2 - dep, -w / 2, z, z + bl, h, m, win, "+x")
                else:
                    facade(sc, w / 2, w / 2 + dep, z, z + bl, h, m, win, "-x")
                z += bl + (rnd.uniform(0, 3) if rnd.random() < 0.3 else 0)
        # kerbs
        kerb = sc.mat("kerb", "concrete")
        for side in (-1, 1):
            xk = side * (w / 2 - rnd.uniform(1.5, 2.5))
            sc.solid("kerb", (min(xk, xk + side * 0.15), 0, -L / 2), (max(xk, xk + side * 0.15), 0.12, L / 2), kerb)
        sc.cells = [(-w / 2 + 0.3, w / 2 - 0.3, -L / 2 + 2, L / 2 - 2)]
        sc.camera_rect = (-w / 4, w / 4, L / 2 - 15, L / 2 - 6)
        sc.heading = rnd.uniform(-25, 25)
    elif kind == "courtyard":
        W, D = rnd.uniform(12, 24), rnd.uniform(12, 24)
        sides = ["-z", "+x", "-x", "+z"][:rnd.randint(3, 4)]
        for f in sides:
            h = rnd.uniform(7, 16)
            m = sc.mat("facade", rnd.choice(facade_kinds))
            if f == "-z":
                facade(sc, -W / 2 - 8, W / 2 + 8, -D / 2 - 8, -D / 2, h, m, win, "+z")
            elif f == "+z":
                facade(sc, -W / 2 - 8, W / 2 + 8, D / 2, D / 2 + 8, h, m, win, "-z")
            elif f == "+x":
                facade(sc, W / 2, W / 2 + 8, -D / 2, D / 2, h, m, win, "-x")
            else:
                facade(sc, -W / 2 - 8, -W / 2, -D / 2, D / 2, h, m, win, "+x")
        sc.cells = [(-W / 2 + 0.3, W / 2 - 0.3, -D / 2 + 0.3, D / 2 - 0.3)]
        sc.camera_rect = (-W / 4, W / 4, D / 6, D / 2 - 2)
        sc.heading = rnd.uniform(-30, 30)
    else:
        S = rnd.uniform(30, 50)
        for _ in range(rnd.randint(3, 6)):
            ang = rnd.uniform(-1.2, 1.2) + math.pi
            dist = rnd.uniform(15, 30)
            cx, cz = math.sin(ang) * dist, -math.cos(ang) * dist
            bw, bd, h = rnd.uniform(8, 16), rnd.uniform(8, 16), rnd.uniform(6, 22)
            facade(sc, cx - bw / 2, cx + bw / 2, cz - bd / 2, cz + bd / 2, h, sc.mat("facade", rnd.choice(facade_kinds)),
                   win, "+z")
        sc.cells = [(-S / 2, S / 2, -12, 12)]
        sc.camera_rect = (-3, 3, 4, 10)
        sc.heading = rnd.uniform(-30, 30)
    # benches / bollards / planters
    stuff = sc.mat("street_furniture", rnd.choice(["concrete", "wood", "paint"]))
    cx = rnd.uniform(sc.camera_rect[0], sc.camera_rect[1])
    cz = rnd.uniform(sc.camera_rect[2], sc.camera_rect[3])
    sc.camera_xz = (cx, cz)
    keep_out = [((cx - 1.0, 0, cz - 1.0), (cx + 1.0, 3, cz + 1.0))]
    for _ in range(rnd.randint(1, 5)):
        w, d, h = rnd.choice([(1.8, 0.5, 0.45), (0.3, 0.3, 0.9), (1.2, 1.2, 0.6), (0.8, 0.8, 0.8)])
        fp = place_footprint(sc, w, d, h, keep_out, False)
        if fp:
            sc.solid("street_object", (fp[0], 0, fp[2]), (fp[1], h, fp[3]), stuff)
    sc.supports = [{"name": "ground", "y": 0.0, "rect": c, "support": "ground"} for c in sc.cells]
    overcast = rnd.random() < 0.35
    if overcast:
        g = rnd.uniform(0.85, 1.0)
        overcast_world(sc, [g, g * rnd.uniform(0.97, 1.0), g * rnd.uniform(0.98, 1.05)], 1.0)
        sc.choices["weather"] = "overcast"
    else:
        elev = math.radians(rnd.uniform(10, 70))
        az = math.radians(rnd.uniform(0, 360))
        sun_dir = np.array([math.cos(elev) * math.sin(az), math.sin(elev), math.cos(elev) * math.cos(az)])
        clear_sky_world(sc, sun_dir, rnd.choice(["NISHITA", "HOSEK_WILKIE"]))
        add_sun(sc, sun_dir, 1.0, rnd.uniform(0.5, 1.5), rnd.choice([5000, 5500, 6000, 6500]))
        sc.choices["weather"] = "sun"
        sc.choices["sun_ratio"] = rnd.uniform(3.0, 8.0)
    sc.choices["sky_target_radiance"] = 1.0
    return sc
