"""A scene kept twice: Blender objects (Cycles) and a SCENE.json with OBJ
meshes for `propcam render`, built from the same numbers in our coordinates
(Y up, metres) with the conversions of units.py. Shared by the units check
(units_check.py) and the renderer bench (cycles_bench.py)."""
import json
import math
import os
import shutil

import bpy
import numpy as np

import bcommon
import units


def write_obj(path, verts, faces, normals=None):
    """faces: vertex index tuples (0-based); normals: one per vertex (smooth
    shading, written as `f a//a`) or None (flat)."""
    with open(path, "w") as f:
        for v in verts:
            f.write("v %.6f %.6f %.6f\n" % tuple(v))
        for n in normals if normals is not None else ():
            f.write("vn %.6f %.6f %.6f\n" % tuple(n))
        for fc in faces:
            if normals is None:
                f.write("f " + " ".join(str(i + 1) for i in fc) + "\n")
            else:
                f.write("f " + " ".join("%d//%d" % (i + 1, i + 1) for i in fc) + "\n")


def triangles(faces):
    """Fans each polygon from its first corner, as Cycles splits quads."""
    return [(q[0], q[i], q[i + 1]) for q in faces for i in range(1, len(q) - 1)]


def material_spec(material):
    """A SCENE.json material from a dict, or a grey/RGB diffuse albedo."""
    if isinstance(material, dict):
        spec = dict(material)
    else:
        spec = {"type": "diffuse", "albedo": material}
    if "albedo" in spec and not isinstance(spec["albedo"], (list, tuple)):
        spec["albedo"] = [float(spec["albedo"])] * 3
    return spec


def load_image_linear(path):
    """An EXR written by `propcam render` as H x W x 3 (row 0 = top)."""
    img = bpy.data.images.load(path)
    px = np.empty(img.size[0] * img.size[1] * 4, np.float32)
    img.pixels.foreach_get(px)
    out = px.reshape(img.size[1], img.size[0], 4)[::-1, :, :3].copy()
    bpy.data.images.remove(img)
    return out


class TwinScene:
    """Resets Blender's scene; every add_* call adds to both renderers."""

    def __init__(self, folder, width, height, threads):
        self.dir, self.w, self.h = folder, width, height
        os.makedirs(folder, exist_ok=True)
        bcommon.reset_scene(width, height, threads)
        self.meshes, self.lights, self.n = [], [], 0

    def _next(self):
        self.n += 1
        return self.n

    def box(self, lo, hi, material, inward=False):
        """Axis-aligned box (a room when inward); material: albedo or spec."""
        x0, y0, z0 = lo
        x1, y1, z1 = hi
        v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1),
             (x0, y1, z1)]
        f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (3, 7, 6, 2), (0, 4, 7, 3), (1, 2, 6, 5)]
        if inward:
            f = [tuple(reversed(q)) for q in f]
        i = self._next()
        fn = "mesh_%d.obj" % i
        spec = material_spec(material)
        write_obj(os.path.join(self.dir, fn), v, triangles(f))
        self.meshes.append({"file": fn, "material": spec})
        bcommon.mesh_object("m%d" % i, v, f, bcommon.prop_material("d%d" % i, spec))

    def uv_sphere(self, center, radius, material, segments=48, rings=24):
        """Blender's smooth UV sphere; the OBJ gets its vertices and its vertex
        normals, so both renderers shade the same polygons the same way."""
        i = self._next()
        spec = material_spec(material)
        self._uv_sphere(i, center, radius, spec, bcommon.prop_material("d%d" % i, spec), segments, rings)

    def emissive_sphere(self, center, radius, color, strength, segments=48, rings=24):
        """uv_sphere glowing with radiance strength * colour (_emissive)."""
        i = self._next()
        spec, mat = self._emissive(i, color, strength)
        self._uv_sphere(i, center, radius, spec, mat, segments, rings)

    def emissive_tube(self, a, b, radius, color, strength, segments=24):
        """A closed cylinder from a to b (flat polygons, capped, outward), glowing
        with radiance strength * colour (_emissive)."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        d = (b - a) / np.linalg.norm(b - a)
        u = np.cross(d, [0.0, 1.0, 0.0] if abs(d[1]) < 0.9 else [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(d, u)  # u x v = d
        ring = [radius * (math.cos(2 * math.pi * k / segments) * u + math.sin(2 * math.pi * k / segments) * v)
                for k in range(segments)]
        verts = [tuple(a + p) for p in ring] + [tuple(b + p) for p in ring]
        n = segments
        faces = [(k, (k + 1) % n, n + (k + 1) % n, n + k) for k in range(n)]
        faces += [tuple(reversed(range(n))), tuple(range(n, 2 * n))]
        i = self._next()
        spec, mat = self._emissive(i, color, strength)
        fn = "mesh_%d.obj" % i
        write_obj(os.path.join(self.dir, fn), verts, triangles(faces))
        self.meshes.append({"file": fn, "material": spec})
        bcommon.mesh_object("t%d" % i, verts, faces, mat)

    @staticmethod
    def _emissive(i, color, strength):
        """(SCENE.json material, Blender material) of an emissive mesh: ours
        `emissive` of radiance strength * colour (units.mesh_emission_radiance),
        Cycles an Emission shader of that strength and colour on both sides
        (as ours) that is sampled as a light ("Multiple Importance" on)."""
        m = bcommon.emission_material("e%d" % i, color, strength, one_sided=False, emitter_aov=False)
        if hasattr(m, "emission_sampling"):  # Blender 4.0+
            m.emission_sampling = "AUTO"
        else:
            m.cycles.sample_as_light = True
        return {"type": "emissive", "emission": units.mesh_emission_radiance(color, strength)}, m

    def _uv_sphere(self, i, center, radius, spec, mat, segments, rings):
        obj = bcommon.uv_sphere("s%d" % i, center, radius, mat, segments, rings)
        me = obj.data
        c = np.asarray(center, float)
        verts = [np.asarray(units.from_blender(v.co)) + c for v in me.vertices]
        normals = [units.from_blender(v.normal) for v in me.vertices]
        faces = [tuple(p.vertices) for p in me.polygons]
        fn = "mesh_%d.obj" % i
        write_obj(os.path.join(self.dir, fn), verts, triangles(faces), normals)
        self.meshes.append({"file": fn, "material": spec})

    def camera(self, center, yaw, pitch, fov_deg):
        """Pinhole of horizontal field of view fov_deg (units.camera_rotation angles)."""
        f = (self.w / 2) / math.tan(math.radians(fov_deg) / 2)
        self.R = units.camera_rotation(yaw, pitch, 0.0)
        self.K = {"fx": f, "fy": f, "cx": (self.w - 1) / 2, "cy": (self.h - 1) / 2}
        self.center = center
        bcommon.set_camera(self.R, center, f, self.w, self.h)

    def in_view(self, p):
        u, v, z = units.project(self.K, self.R, self.center, p)
        return z > 0 and -0.5 <= u <= self.w - 0.5 and -0.5 <= v <= self.h - 0.5

    def area_light(self, center, normal, size, color, radiance):
        """One-sided rectangle size = (w, h), w along +X for a vertical normal,
        else along Y x normal (render/README.md); radiance colour * radiance."""
        n = np.asarray(normal, float)
        u = np.array([1.0, 0, 0]) if abs(n[1]) > 0.999 * np.linalg.norm(n) else np.cross([0, 1.0, 0], n)
        bcommon.area_light("area%d" % self._next(), center, n, u, size[0], size[1], color, radiance)
        self.lights.append({"type": "area", "position": list(center), "normal": list(normal), "size": list(size),
                            "intensity": [float(c) * radiance for c in color]})

    def sphere_light(self, center, radius, color, radiance):
        """A Cycles POINT light of soft radius r = our sphere light (units.py)."""
        bcommon.point_light("bulb%d" % self._next(), center, radius, color, radiance)
        self.lights.append({"type": "sphere", "position": list(center), "radius": radius,
                            "intensity": [float(c) * radiance for c in color]})

    def environment(self, exr_path, scale, name="env.exr"):
        """The map copied beside the SCENE.json (its files must stay inside its folder)."""
        shutil.copy(exr_path, os.path.join(self.dir, name))
        bcommon.set_world_environment(os.path.join(self.dir, name), scale)
        self.lights.append({"type": "ibl", "file": name, "intensity": scale})

    def write_scene_json(self):
        scene = {"camera": {"K": self.K, "R_world_from_cam": np.asarray(self.R).tolist(), "center": list(self.center),
                            "width": self.w, "height": self.h},
                 "meshes": self.meshes, "lights": self.lights}
        path = os.path.join(self.dir, "scene.json")
        with open(path, "w") as f:
            json.dump(scene, f, indent=1)
        return path
