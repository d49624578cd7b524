#include <gtest/gtest.h>
#include "propcam/inference/infer.h"
#include "propcam/inference/contact_depth.h"
#include "propcam/capture/image_file.h"
namespace propcam::inference {
TEST(Scratch, Om) {
  for (std::string f : {"/tmp/hotel.png"}) {
    cv::Mat photo = capture::load_photo_linear(f);
    GeometryEstimate g = infer_geometry(photo, {});
    capture::write_image(f + ".om.png", orientation_map_to_color(g.orientation));
    ContactDepth c = contact_depth_target(g.orientation, g.pinhole, g.layout.normals);
    cv::Mat v; c.depth.convertTo(v, CV_32F, 0.2); cv::Mat v3; cv::merge(std::vector<cv::Mat>{v, v, v}, v3);
    capture::write_image(f + ".contact.exr", v3);
    cv::Mat b; g.layout.depth.convertTo(b, CV_32F, 0.2); cv::merge(std::vector<cv::Mat>{b, b, b}, v3);
    capture::write_image(f + ".box.exr", v3);
    InferenceOptions o; o.geometry.contact_weight = 0;
    GeometryEstimate g2 = infer_geometry(photo, o);
    cv::Mat n = (g2.normals + 1) * 0.5; capture::write_image(f + ".nocontact_normals.exr", n);
  }
}
}
