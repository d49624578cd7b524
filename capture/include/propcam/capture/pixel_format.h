// The one conversion from a camera's bytes to an image, used for live and
// replayed frames alike. YUV is converted with the frame's encoding
// (BT.601/709) and range (limited/full); MJPEG is decoded by libjpeg-turbo.
#pragma once

#include <opencv2/core.hpp>

#include "propcam/capture/frame.h"

namespace propcam::capture {

// CV_8UC3, RGB order, sRGB-encoded as the camera delivered it. Throws
// std::runtime_error on a frame whose bytes do not match its format
// (too short, bad stride, a corrupt JPEG).
cv::Mat frame_to_rgb8(const Frame& frame);

// CV_32FC3 linear RGB (the sRGB curve undone), what inference takes.
cv::Mat frame_to_linear(const Frame& frame);

// The inverse, for tests, recordings of synthetic scenes and the virtual
// camera: packs an 8-bit RGB image into `format` (MJPEG at `jpeg_quality`).
Frame rgb8_to_frame(const cv::Mat& rgb8, const FrameFormat& format, int jpeg_quality = 92);

}  // namespace propcam::capture
