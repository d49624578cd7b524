// Cameras by id, across backends, as rpicam-apps picks them: each backend
// lists what it finds; an id names its backend ("v4l2:/dev/video0",
// "libcamera:<libcamera id>", "replay:<recording folder>").
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "propcam/capture/frame_source.h"

namespace propcam::capture {

// Every camera the backends can see now (libcamera first, then V4L2 capture
// nodes libcamera does not already own), plus the replay recordings found
// in `recording_dirs`.
std::vector<CameraInfo> list_cameras(const std::vector<std::string>& recording_dirs = {});

// Opens the camera with this id ("libcamera:auto": libcamera's first camera).
// Throws std::runtime_error naming the id
// and the reason when it cannot be opened.
std::unique_ptr<FrameSource> open_camera(const std::string& id);

}  // namespace propcam::capture
