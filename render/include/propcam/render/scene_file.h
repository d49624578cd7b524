// SCENE.json: a plain scene description (camera, OBJ meshes, lights) that
// `propcam render` turns into an image, so the renderer can be compared with
// other renderers on the same scene. The format is documented in
// render/README.md.
//
// Every file a scene names (meshes, environment maps) is a path relative to
// the JSON's folder and must stay inside it: absolute paths and paths that
// climb out of the folder with ".." are refused.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "propcam/render/camera.h"
#include "propcam/render/lights.h"
#include "propcam/render/mesh.h"
#include "propcam/render/scene.h"

namespace propcam::render {

struct SceneFile {
  std::string path;          // the JSON file
  PinholeCamera camera;
  std::vector<Mesh> meshes;  // in world coordinates, with their materials resolved
  LightRig lights;
};

// Reads and checks a scene file. Throws std::runtime_error naming the file and
// the offending field ("meshes[1].material.roughness: ...") for a missing or
// unknown field, a wrong type, a non-finite or out-of-range number, a camera
// rotation that is not one, a missing file or a path leaving the folder.
SceneFile load_scene_file(const std::string& path);

// The meshes built into a committed Embree scene (all in the background layer).
std::unique_ptr<Scene> build_scene(const SceneFile& file);

}  // namespace propcam::render
