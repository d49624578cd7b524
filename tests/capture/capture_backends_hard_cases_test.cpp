// Hard cases for opening and listing the live backends: paths that are not
// cameras must give an error naming the path and the reason, never hang,
// crash or be listed.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "propcam/capture/libcamera_source.h"
#include "propcam/capture/v4l2_source.h"

namespace propcam::capture {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("propcam_backends_hard_" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string open_error(const std::string& path) {
  try {
    V4l2Source source(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(opened)";
}

void expect_error(const std::string& path, const std::string& reason) {
  const std::string message = open_error(path);
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find(reason), std::string::npos) << message;
}

TEST(CaptureBackendsHardCases, RegularFileIsNotAV4l2Device) {
  const fs::path file = scratch("regular") / "video0";
  std::ofstream(file) << "not a camera";
  expect_error(file.string(), "not a V4L2 device");
}

TEST(CaptureBackendsHardCases, DirectoryCannotBeOpened) {
  const fs::path dir = scratch("directory");
  expect_error(dir.string(), "Is a directory");
}

TEST(CaptureBackendsHardCases, PathThatVanishedBeforeOpening) {
  const fs::path file = scratch("vanished") / "video0";
  std::ofstream(file) << "x";
  fs::remove(file);
  expect_error(file.string(), "No such file");
}

TEST(CaptureBackendsHardCases, DanglingSymlinkLikeAnUnpluggedCamera) {
  // udev's /dev/v4l/by-id links point at nodes that disappear on unplug.
  const fs::path dir = scratch("dangling");
  fs::create_symlink(dir / "gone", dir / "usb-cam-video-index0");
  expect_error((dir / "usb-cam-video-index0").string(), "No such file");
}

TEST(CaptureBackendsHardCases, FifoDoesNotBlockAndIsRejected) {
  const fs::path fifo = scratch("fifo") / "video0";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  expect_error(fifo.string(), "not a character device");
}

TEST(CaptureBackendsHardCases, CharacterDevicesThatAreNotCameras) {
  for (const std::string path : {"/dev/zero", "/dev/urandom"})
    if (fs::exists(path)) expect_error(path, "VIDIOC_QUERYCAP");
}

TEST(CaptureBackendsHardCases, EmptyPath) { expect_error("", "cannot open"); }

TEST(CaptureBackendsHardCases, ListingSkipsEverythingThatIsNotACaptureNode) {
  const fs::path dir = scratch("fake_dev");
  std::ofstream(dir / "video0") << "file";
  fs::create_directories(dir / "video1");
  fs::create_symlink(dir / "gone", dir / "video2");
  fs::create_symlink("/dev/null", dir / "video3");
  ASSERT_EQ(::mkfifo((dir / "video4").c_str(), 0600), 0);
  std::ofstream(dir / "videoX") << "not a node name";
  std::ofstream(dir / "video99999999999999999999") << "a number too long for an int";
  EXPECT_TRUE(list_v4l2_cameras(dir.string()).empty());
}

TEST(CaptureBackendsHardCases, ListingAMissingOrUnreadableDirectory) {
  EXPECT_TRUE(list_v4l2_cameras("/propcam/no/such/dir").empty());
  EXPECT_TRUE(list_v4l2_cameras("/dev/null").empty());  // not a directory
  EXPECT_TRUE(list_v4l2_cameras("").empty());
}

TEST(CaptureBackendsHardCases, LibcameraIdsThatAreNotCameras) {
  for (const std::string& id : {std::string(), std::string("/dev/video0"), std::string("v4l2:/dev/video0"),
                                std::string(4096, 'x')}) {
    try {
      LibcameraSource source(id);
      ADD_FAILURE() << "opened '" << id << "'";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("libcamera"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace propcam::capture
