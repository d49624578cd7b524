// Mesh files: Wavefront OBJ with its MTL materials, in and out.
//
// MTL -> Material (save_obj writes the inverse):
//   Ke non-zero                          -> Emissive: emission = Ke, albedo = Kd
//   illum 4, 6 or 7 (refraction)         -> Dielectric: ior = Ni (1.5 when absent or 1),
//                                                     roughness from Ns
//   illum 3, or a bright Ks over a dark
//   Kd (max(Ks) >= 0.5, max(Kd) <= 0.1)  -> Metal:    albedo = Ks, roughness from Ns
//   Ks non-zero                          -> Plastic:  albedo = Kd, specular = max(Ks),
//                                                     roughness from Ns
//   otherwise                            -> Diffuse:  albedo = Kd
// Roughness (GGX alpha) = sqrt(2 / (Ns + 2)); colours are clamped to [0, 1].
// map_Kd -> texture: sRGB file -> linear RGB CV_32FC3, path relative to its .mtl.
// Mesh uvs follow the renderer's image convention (v down: row = v * rows);
// the OBJ's v-up texture coordinates are flipped on load and on save.
#pragma once

#include <cstdint>
#include <string>

#include "propcam/render/mesh.h"

namespace propcam::render {

// Budgets of load_mesh_file. Props come from USB sticks, so any file must load in bounded time and memory: a file
// over a count is refused before it is parsed (a texture before it is decoded), the message naming the file, the
// count and the limit. A triangle costs the Mesh 16 bytes and a vertex 32: at both limits it holds 160 MiB.
inline constexpr std::uint64_t kMaxMeshTriangles = std::uint64_t{1} << 21;  // 2097152, after triangulation
// Each of the file's v, vt and vn lines, and the mesh's vertices (distinct position, uv and normal triples).
inline constexpr std::uint64_t kMaxMeshVertices = std::uint64_t{1} << 22;  // 4194304
inline constexpr std::uint64_t kMaxMeshMaterials = 4096;                   // newmtl entries over all its .mtl files
// A texture whose longer side exceeds this is reduced on read (aspect kept, area-averaged): 4096 x 4096 as float
// RGB is 192 MiB.
inline constexpr int kMaxTextureSide = 4096;
// Pixels decoded for one mesh's textures, counted from their headers before decoding: four 4096 x 4096 maps. A
// JPEG over the side limit decodes at 1/2, 1/4 or 1/8 of its size, as small as keeps its longer side at
// kMaxTextureSide or above (smaller to fit the budget), and counts at that size; another format over it counts at
// its reduced size.
inline constexpr std::uint64_t kMaxTextureDecodePixels = std::uint64_t{1} << 26;
// A texture file of another format over the side limit is reduced while it is read, a band of rows at a time
// (memory for the reduced texture and one band; time linear in the file's pixels), up to this many pixels.
inline constexpr std::uint64_t kMaxTextureFilePixels = std::uint64_t{1} << 28;  // 16384 x 16384

// Loads an .obj file and the .mtl files it names. Polygons are triangulated and
// corners with different position/uv/normal index triples become separate
// vertices. Missing normals are computed (smooth, but faces meeting at more than
// 60 degrees keep separate normals); faces without a material get a default
// grey diffuse one.
// Polygons of more than 64 corners are split as a fan from their first corner
// (smaller ones by tinyobjloader's ear clipping). Loading takes time linear in
// the file's size and the textures' pixels.
// Throws std::runtime_error naming the file when it is missing, unparsable,
// over a budget above, holds no triangles or non-finite numbers, or a texture
// cannot be read.
Mesh load_mesh_file(const std::string& path);

// Writes `path` (.obj) and a sibling .mtl (same stem), plus one PNG per textured
// material. Each file is written under a temporary name and renamed into place,
// the .obj last, so readers never see a partial file.
// Throws std::runtime_error naming the file on failure.
void save_obj(const Mesh& mesh, const std::string& path);

}  // namespace propcam::render
