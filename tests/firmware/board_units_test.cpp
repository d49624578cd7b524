// The board's systemd units, udev rules and install layout, and propcamd's
// sd_notify protocol (READY / WATCHDOG / STOPPING) without systemd.
#include <gtest/gtest.h>

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

const fs::path kSource = PROPCAM_SOURCE_DIR;

fs::path make_temp_dir(const std::string& name) {
  std::string pattern = (fs::temp_directory_path() / ("propcam_" + name + "_XXXXXX")).string();
  if (!mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
  return pattern;
}

struct ShellRun {
  int exit_code;
  std::string out;  // stdout and stderr
};

ShellRun sh(const std::string& cmd) {
  ShellRun r{0, ""};
  FILE* pipe = popen((cmd + " 2>&1").c_str(), "r");
  if (!pipe) return {-1, "popen failed"};
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), buf.size(), pipe)) r.out += buf.data();
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void replace_all(std::string& s, const std::string& from, const std::string& to) {
  for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
    s.replace(at, from.size(), to);
}

// ---- systemd-analyze verify -------------------------------------------------

TEST(BoardUnits, SystemdAnalyzeVerifiesBothUnits) {
  if (sh("command -v systemd-analyze").exit_code != 0) GTEST_SKIP() << "systemd-analyze is not installed";
  const fs::path dir = make_temp_dir("units");
  // verify checks that ExecStart's binary exists: point it at the built ones.
  const std::string stick = (kSource / "board/stick/propcam-stick").string();
  const std::vector<std::array<std::string, 3>> units = {  // file, installed program, built program
      {"propcamd.service", "/usr/bin/propcamd ", PROPCAMD},
      {"propcam.service", "/usr/bin/propcam ", PROPCAM_CLI},
      {"propcam-stick@.service", "/usr/libexec/propcam/propcam-stick ", stick}};
  std::string paths;
  for (const auto& [name, installed, built] : units) {
    std::string text = read_text(kSource / "board/systemd" / name);
    ASSERT_NE(text.find("ExecStart=" + installed), std::string::npos) << name;
    replace_all(text, "ExecStart=" + installed, "ExecStart=" + built + " ");
    replace_all(text, "ExecStop=" + installed, "ExecStop=" + built + " ");
    replace_all(text, "ExecStopPost=" + installed, "ExecStopPost=" + built + " ");
    // A template is verified as one of its instances.
    const std::string file = name == "propcam-stick@.service" ? "propcam-stick@sda1.service" : name;
    std::ofstream(dir / file) << text;
    paths += ' ';  // not " " + string: GCC 12 warns falsely (-Wrestrict)
    paths += (dir / file).string();
  }
  const ShellRun r = sh("cd " + dir.string() + " && timeout 120 systemd-analyze verify --man=no" + paths);
  fs::remove_all(dir);
  // It exits 0 on unknown keys, so the output is what counts; a failure that
  // names neither unit is the container (no systemd), not ours.
  if (r.exit_code != 0 && r.out.find("propcam") == std::string::npos)
    GTEST_SKIP() << "systemd-analyze cannot run here (exit " << r.exit_code << "): " << r.out;
  std::istringstream lines(r.out);
  std::string line, ours;
  while (std::getline(lines, line))
    if (line.find("propcam") != std::string::npos) ours += line + "\n";
  EXPECT_EQ(ours, "") << "systemd-analyze verify about our units";
  EXPECT_EQ(r.exit_code, 0) << r.out;
}

TEST(BoardUnits, UnitsAskForTheHardening) {
  for (const char* name : {"propcamd.service", "propcam.service"}) {
    const std::string text = read_text(kSource / "board/systemd" / name);
    for (const char* line : {"Type=notify", "Restart=on-failure", "User=propcam", "ProtectSystem=strict",
                             "ProtectHome=yes", "PrivateTmp=yes", "NoNewPrivileges=yes", "DevicePolicy=closed",
                             "CapabilityBoundingSet=\n", "SystemCallArchitectures=native", "IPAddressDeny=any"})
      EXPECT_NE(text.find(std::string("\n") + line), std::string::npos) << name << " lacks " << line;
    EXPECT_NE(text.find("\nWatchdogSec="), std::string::npos) << name;
    // No IP socket family may be allowed: no network port.
    std::smatch m;
    ASSERT_TRUE(std::regex_search(text, m, std::regex("\nRestrictAddressFamilies=([^\n]*)"))) << name;
    EXPECT_EQ(m[1].str().find("AF_INET"), std::string::npos) << name;
  }
}

// ---- sd_notify, end to end without systemd ----------------------------------

// Reads notify datagrams until `done` says so or `limit_ms` passes.
template <typename Done>
void receive_notifications(int fd, std::vector<std::string>& got, int limit_ms, Done done) {
  for (int waited = 0; waited < limit_ms && !done(); waited += 50) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, 50) <= 0) continue;
    std::array<char, 4096> buf{};
    const ssize_t n = recv(fd, buf.data(), buf.size() - 1, 0);
    if (n <= 0) continue;
    std::istringstream lines(std::string(buf.data(), static_cast<std::size_t>(n)));
    std::string line;
    while (std::getline(lines, line))
      if (!line.empty()) got.push_back(line);
  }
}

TEST(BoardUnits, PropcamdSpeaksSdNotify) {
  const fs::path dir = make_temp_dir("notify");
  const std::string notify_path = (dir / "notify.sock").string();
  const std::string capture_path = (dir / "capture.sock").string();
  const int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(fd, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  ASSERT_LT(notify_path.size(), sizeof(addr.sun_path));
  std::copy(notify_path.begin(), notify_path.end(), addr.sun_path);
  ASSERT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);

  const std::string camera = "replay:" + (kSource / "board/virtual/recordings/living_room").string();
  const pid_t daemon = fork();
  ASSERT_GE(daemon, 0);
  if (daemon == 0) {
    // As systemd would: WATCHDOG_PID names this very process.
    setenv("NOTIFY_SOCKET", notify_path.c_str(), 1);
    setenv("WATCHDOG_USEC", "200000", 1);
    setenv("WATCHDOG_PID", std::to_string(getpid()).c_str(), 1);
    execl(PROPCAMD, PROPCAMD, "--socket", capture_path.c_str(), "--camera", camera.c_str(),
          static_cast<char*>(nullptr));
    _exit(127);
  }

  std::vector<std::string> got;
  auto count_after_ready = [&](const std::string& what) {
    int n = 0;
    bool ready = false;
    for (const auto& line : got) {
      if (line == "READY=1") ready = true;
      else if (ready && line == what) ++n;
    }
    return n;
  };
  // Bounded waits (20 s each) for what must come, no assertion on timing.
  receive_notifications(fd, got, 20000, [&] { return count_after_ready("WATCHDOG=1") >= 3; });
  const bool socket_was_there = fs::exists(capture_path);
  kill(daemon, SIGTERM);
  receive_notifications(fd, got, 20000, [&] { return count_after_ready("STOPPING=1") >= 1; });
  int status = 0;
  waitpid(daemon, &status, 0);
  close(fd);
  fs::remove_all(dir);

  std::string all;
  for (const auto& line : got) all += line + "\n";
  EXPECT_NE(std::find(got.begin(), got.end(), "READY=1"), got.end()) << all;
  EXPECT_TRUE(socket_was_there) << "READY=1 comes once the socket listens";
  EXPECT_GE(count_after_ready("WATCHDOG=1"), 3) << all;
  EXPECT_EQ(count_after_ready("STOPPING=1"), 1) << all;
  EXPECT_TRUE(std::any_of(got.begin(), got.end(),
                          [](const std::string& l) { return l.starts_with("STATUS=camera ") && l.ends_with(" open"); }))
      << all;
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "propcamd stops cleanly on SIGTERM";
}

// ---- udev rules ---------------------------------------------------------------

// udevadm verify is not in bookworm: each rule must be known keys with the
// operators udev accepts for them, at least one match and one assignment.
TEST(BoardUnits, UdevRulesParse) {
  const std::set<std::string> match_keys = {"ACTION", "DEVPATH",  "KERNEL", "KERNELS", "SUBSYSTEM", "SUBSYSTEMS",
                                            "DRIVER", "DRIVERS",  "ATTR",   "ATTRS",   "ENV",       "TAG",
                                            "TAGS",   "TEST",     "PROGRAM", "RESULT", "NAME",      "SYMLINK",
                                            "CONST",  "SYSCTL"};
  const std::set<std::string> assign_keys = {"NAME",  "SYMLINK", "OWNER", "GROUP", "MODE",   "ENV",     "TAG",
                                             "RUN",   "LABEL",   "GOTO",  "IMPORT", "OPTIONS", "ATTR",   "SYSCTL"};
  const std::regex token(R"(^([A-Z_]+)(\{[^}]+\})?(==|!=|\+=|-=|:=|=)\"([^\"]*)\"$)");
  std::ifstream in(kSource / "board/udev/60-propcam.rules");
  ASSERT_TRUE(in) << "board/udev/60-propcam.rules";
  std::string line;
  int number = 0, rules = 0;
  while (std::getline(in, line)) {
    ++number;
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    ASSERT_NE(line.back(), '\\') << "line " << number << ": no continuations in our rules";
    int matches = 0, assignments = 0;
    std::stringstream parts(line.substr(first));
    std::string part;
    while (std::getline(parts, part, ',')) {
      part.erase(0, part.find_first_not_of(' '));
      part.erase(part.find_last_not_of(' ') + 1);
      std::smatch m;
      ASSERT_TRUE(std::regex_match(part, m, token)) << "line " << number << ": " << part;
      const std::string key = m[1], op = m[3], value = m[4];
      if (op == "==" || op == "!=") {
        EXPECT_TRUE(match_keys.count(key)) << "line " << number << ": " << key << " is not a match key";
        ++matches;
      } else {
        EXPECT_TRUE(assign_keys.count(key)) << "line " << number << ": " << key << " is not an assignment key";
        ++assignments;
      }
      if (key == "GROUP") {
        EXPECT_TRUE(value == "gpio" || value == "video" || value == "input") << value;
      }
      if (key == "MODE") {
        EXPECT_EQ(value, "0660") << "line " << number;
      }
    }
    EXPECT_GT(matches, 0) << "line " << number;
    EXPECT_GT(assignments, 0) << "line " << number;
    ++rules;
  }
  EXPECT_GE(rules, 5);
}

// ---- sysusers and tmpfiles, applied to a temp root --------------------------

TEST(BoardUnits, SysusersAndTmpfilesApplyToATempRoot) {
  if (sh("command -v systemd-sysusers && command -v systemd-tmpfiles").exit_code != 0)
    GTEST_SKIP() << "systemd-sysusers / systemd-tmpfiles are not installed";
  const fs::path root = make_temp_dir("sysroot");
  fs::create_directories(root / "etc");
  const ShellRun users = sh("timeout 60 systemd-sysusers --root=" + root.string() + " " +
                       (kSource / "board/systemd/propcam.sysusers.conf").string());
  ASSERT_EQ(users.exit_code, 0) << users.out;
  const std::string passwd = read_text(root / "etc/passwd"), group = read_text(root / "etc/group");
  EXPECT_NE(passwd.find("propcam:x:"), std::string::npos) << passwd;
  for (const char* g : {"propcam", "gpio", "video", "plugdev", "input"})
    EXPECT_TRUE(std::regex_search(group, std::regex(std::string("(^|\n)") + g + ":x:"))) << g << "\n" << group;
  EXPECT_TRUE(std::regex_search(group, std::regex("(^|\n)gpio:x:[0-9]+:propcam"))) << group;
  // tmpfiles resolves propcam from the temp root's passwd; chown needs root.
  if (getuid() != 0) {
    fs::remove_all(root);
    GTEST_SKIP() << "systemd-tmpfiles needs root to chown (sysusers checked)";
  }
  const ShellRun dirs = sh("timeout 60 systemd-tmpfiles --root=" + root.string() + " --create " +
                      (kSource / "board/systemd/propcam.tmpfiles.conf").string());
  EXPECT_EQ(dirs.exit_code, 0) << dirs.out;
  EXPECT_TRUE(fs::is_directory(root / "var/spool/propcam"));
  EXPECT_TRUE(fs::is_directory(root / "media/propcam"));
  fs::remove_all(root);
}

// ---- install layout (cmake --install, the package's files) ------------------

std::set<std::string> files_under(const fs::path& root) {
  std::set<std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (!e.is_directory()) files.insert(fs::relative(e.path(), root).string());
  return files;
}

// The value of `key=` on a unit's line that starts with it ("" if none).
std::string unit_value(const std::string& text, const std::string& key) {
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);)
    if (line.rfind(key + "=", 0) == 0) return line.substr(key.size() + 1);
  return "";
}

TEST(BoardUnits, InstallPutsEveryFileWhereDebianKeepsIt) {
  const fs::path build = PROPCAM_BINARY_DIR;
  if (read_text(build / "CMakeCache.txt").find("CMAKE_INSTALL_PREFIX:PATH=/usr\n") == std::string::npos)
    GTEST_SKIP() << "this build's prefix is not /usr (only the release preset's is)";
  const fs::path root = make_temp_dir("destdir");
  const ShellRun r = sh("DESTDIR=" + root.string() + " cmake --install " + build.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const std::set<std::string> files = files_under(root);
  for (const char* f : {"usr/bin/propcam", "usr/bin/propcamd", "usr/share/propcam/inference/depth_db.bin",
                        "usr/share/propcam/inference/scene_refs.bin", "usr/share/propcam/inference/scene_classifier.yml.gz",
                        "usr/share/propcam/inference/light_classifier.yml.gz", "usr/share/propcam/inference/ibl_ranker.yml.gz",
                        "usr/share/propcam/board/virtual/board.json", "usr/share/propcam/board/virtual/demo_session.buttons",
                        "usr/share/propcam/board/virtual/recordings/living_room/recording.json",
                        "usr/share/doc/propcam/README.systemd.md", "etc/propcam/boards/rpi/board.json",
                        "etc/propcam/boards/usb-webcam/board.json", "etc/propcam/propcam.env", "etc/propcam/propcamd.env",
                        "lib/systemd/system/propcam.service", "lib/systemd/system/propcamd.service",
                        "lib/systemd/system/propcam-stick@.service", "usr/libexec/propcam/propcam-stick",
                        "usr/lib/sysusers.d/propcam.conf", "usr/lib/tmpfiles.d/propcam.conf",
                        "lib/udev/rules.d/60-propcam.rules"})
    EXPECT_TRUE(files.count(f)) << f << " is not installed";
  // Nothing outside Debian's places for a package's files.
  const std::vector<std::string> places = {"usr/bin/", "usr/libexec/propcam/", "usr/share/propcam/", "usr/share/doc/propcam/", "etc/propcam/",
                                           "lib/systemd/system/", "lib/udev/rules.d/", "usr/lib/sysusers.d/",
                                           "usr/lib/tmpfiles.d/"};
  for (const std::string& f : files)
    EXPECT_TRUE(std::any_of(places.begin(), places.end(), [&](const std::string& p) { return f.rfind(p, 0) == 0; }))
        << f << " is outside Debian's places";
  EXPECT_TRUE((fs::status(root / "usr/bin/propcamd").permissions() & fs::perms::owner_exec) != fs::perms::none);

  // The units start what was installed, on a board that was installed.
  for (const char* unit : {"propcam.service", "propcamd.service", "propcam-stick@.service"}) {
    const std::string text = read_text(root / "lib/systemd/system" / unit);
    const std::string exec = unit_value(text, "ExecStart");
    const std::string program = exec.substr(0, exec.find(' '));
    EXPECT_TRUE(fs::exists(root / program.substr(1))) << unit << " starts " << program << ", which is not installed";
  }
  const std::string board =
      unit_value(read_text(root / "lib/systemd/system/propcam.service"), "Environment").substr(std::string("PROPCAM_BOARD=").size());
  EXPECT_TRUE(fs::exists(root / board.substr(1))) << "the default board " << board << " is not installed";
  fs::remove_all(root);
}

// ---- the USB stick ---------------------------------------------------------------

// propcam-stick on a real block device (a loop device over an image): root
// and losetup needed. The stick must end up writable by an unprivileged user.
TEST(BoardUnits, StickHelperMountsAStickWritableForTheServiceUser) {
  if (geteuid() != 0) GTEST_SKIP() << "mounting needs root";
  if (sh("command -v losetup && command -v mkfs.ext4 && command -v setfacl && command -v setpriv").exit_code != 0)
    GTEST_SKIP() << "losetup, mkfs.ext4, setfacl or setpriv missing";
  const std::string helper = (kSource / "board/stick/propcam-stick").string();
  const fs::path dir = make_temp_dir("stick");
  const fs::path image = dir / "stick.img", mount_point = dir / "media";
  // mkdtemp's 0700 would stop the unprivileged user before the stick.
  fs::permissions(dir, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                           fs::perms::others_read | fs::perms::others_exec);
  ASSERT_EQ(sh("truncate -s 16M " + image.string()).exit_code, 0);
  const std::string env = "PROPCAM_STICK_DIR=" + mount_point.string() + " PROPCAM_STICK_USER=nobody ";

  const ShellRun loop = sh("losetup -f --show " + image.string());
  if (loop.exit_code != 0) {
    fs::remove_all(dir);
    GTEST_SKIP() << "no loop device here: " << loop.out;
  }
  const std::string device = loop.out.substr(0, loop.out.find('\n'));

  // No file system: refused, nothing mounted.
  ShellRun r = sh(env + helper + " mount " + device);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("not FAT, exFAT or ext4"), std::string::npos) << r.out;
  EXPECT_NE(sh("mountpoint -q " + mount_point.string()).exit_code, 0);

  // ext4: mounted, its owners kept, and writable by the service's user.
  ASSERT_EQ(sh("mkfs.ext4 -q -F " + device).exit_code, 0);
  r = sh(env + helper + " mount " + device);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(sh("mountpoint -q " + mount_point.string()).exit_code, 0);
  EXPECT_EQ(sh("stat -c %U " + mount_point.string()).out, "root\n");
  r = sh("setpriv --reuid=nobody --regid=nogroup --clear-groups mkdir " + (mount_point / "PropCam").string());
  EXPECT_EQ(r.exit_code, 0) << "the service's user cannot write the stick: " << r.out;
  // A second stick while one is mounted is left alone.
  r = sh(env + helper + " mount " + device);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("already holds a stick"), std::string::npos) << r.out;

  EXPECT_EQ(sh(env + helper + " unmount " + device).exit_code, 0);
  EXPECT_NE(sh("mountpoint -q " + mount_point.string()).exit_code, 0);
  EXPECT_EQ(sh(env + helper + " unmount " + device).exit_code, 0) << "unmounting twice (a pulled stick) is fine";

  r = sh(env + helper + " mount " + image.string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("not a block device"), std::string::npos) << r.out;
  EXPECT_EQ(sh(env + helper + " eject " + device).exit_code, 2);

  sh("losetup -d " + device);
  fs::remove_all(dir);
}

}  // namespace
