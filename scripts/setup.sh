#!/usr/bin/env bash
# Installs the Debian (bookworm) packages PropCam needs:
#   scripts/setup.sh          everything to build, test and run (CI, scripts/test.sh)
#   scripts/setup.sh --demo   only what building and running the demo needs
#                             (scripts/demo.sh): no clang, Blender, QEMU or test tools
# On a board nothing of this is needed: the propcam package's Depends name
# its run-time libraries (README, "Install on a board").
set -euo pipefail

demo_packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config git
  # hardware backends named by the design
  libcamera-dev libv4l-dev libgpiod-dev
  # DRM/KMS display for boards without fbdev emulation (ui_fb DrmDisplay)
  libdrm-dev
  # sd_notify / watchdog for the systemd units (board/systemd)
  libsystemd-dev
  # MJPEG frames (libjpeg-turbo's libjpeg API)
  libjpeg62-turbo-dev
  # vision, geometry, rendering, image files (OpenImageIO's CMake package
  # names its tools: configuring needs openimageio-tools)
  libopencv-dev libopencv-contrib-dev libeigen3-dev libembree-dev libceres-dev
  libopenimageio-dev openimageio-tools
  # libraries the code uses
  libcli11-dev nlohmann-json3-dev libspdlog-dev libtinyobjloader-dev libfreetype-dev fonts-dejavu-core
  # GoogleTest: the release preset configures the tests (the demo builds none)
  libgtest-dev libgmock-dev
  # real photographs for the demo and the tests: OpenCV's sample images, and CC0
  # HDR panoramas (blender-data's studio lights) that real views are cut from
  opencv-doc blender-data
)

dev_packages=(
  # clang with libFuzzer and the sanitizer runtimes (tests/fuzz, scripts/fuzz.sh)
  clang libclang-rt-14-dev
  # benchmarks and their plots
  libbenchmark-dev gnuplot-nox
  # the security tests trace the appliance's sockets and file writes
  strace
  # the USB stick helper lets the service write an ext4 stick (board/stick)
  acl
  # the Blender world (scripts/make_blender_world.sh) and its units check:
  # scenes made and rendered by Cycles, not by our code (its Python uses numpy)
  blender python3-numpy
  # the qemu board (board/qemu/): QEMU, the initramfs (static busybox, cpio, kmod's
  # modprobe/depmod, xz for the vmlinux), the stick's FAT image (dosfstools, mtools),
  # the guest's tools (gpiod, v4l-utils), the VM driver (python3); the kernel and
  # its sources are fetched by board/qemu/fetch.sh (apt-get download)
  qemu-system-x86 busybox-static cpio kmod xz-utils dosfstools mtools gpiod v4l-utils python3
  # the qemu board's libcamera camera (vimc): libcamera lists only devices udevd
  # has initialised, so the guest runs the host's systemd-udevd; cam to check
  # by hand; the IPA modules (vimc's among them) for libcamera's pipelines
  udev libcamera-tools libcamera-ipa
)

packages=("${demo_packages[@]}")
if [[ "${1:-}" != --demo ]]; then packages+=("${dev_packages[@]}"); fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]} == 0)); then
  echo "setup: all ${#packages[@]} packages present"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
