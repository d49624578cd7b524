// The appliance and the capture daemon at run time, as the issue asks of
// them: they run unprivileged (as nobody, when the tests run as root), open no
// IP socket, and write only under their own folders (data, spool, snapshots,
// the stick; propcamd: its runtime folder). Each program runs under
// `strace -f`, and every socket and every call that could change a file
// (open for writing, mkdir, rename, unlink, chmod, a UNIX socket's bind, ...)
// is checked. ctest label: security.
#include <gtest/gtest.h>

#include <grp.h>
#include <pwd.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli_run.h"

namespace {
namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kSource = PROPCAM_SOURCE_DIR;

// What may be touched outside the program's folders: the null device, and
// the registration wait file that LTTng-UST (linked by libcamera) makes in
// shared memory when the library loads (RAM, one per user, not our data).
bool always_allowed(const fs::path& p) {
  return p == "/dev/null" ||
         (p.parent_path() == "/dev/shm" && p.filename().string().starts_with("lttng-ust-wait-"));
}

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

bool strace_works() { return propcam::test::run_shell("strace -f -qq -e trace=none true >/dev/null 2>&1").exit_code == 0; }

// The user the programs run as: nobody/nogroup with no supplementary groups
// when the tests run as root (the devices' groups are not needed on the
// virtual board), else the user running the tests.
struct RunAs {
  bool drop = false;
  uid_t uid = 0;
  gid_t gid = 0;
  std::string prefix;  // "setpriv ... --" or ""
};

RunAs unprivileged_user() {
  RunAs r;
  r.uid = getuid();
  r.gid = getgid();
  if (getuid() != 0) return r;
  const passwd* user = getpwnam("nobody");
  const group* grp = getgrnam("nogroup");
  if (!user || !grp) return r;
  const std::string prefix = "setpriv --reuid=nobody --regid=nogroup --clear-groups --";
  // A checkout under a private folder (/root/...) is out of nobody's reach:
  // then the programs run as this user, still traced.
  const std::string reach = prefix + " test -x " + quote(PROPCAM_CLI) + " -a -x " + quote(PROPCAMD) + " -a -r " +
                            quote((kSource / "board/virtual/board.json").string()) + " -a -x " +
                            quote(PROPCAM_BINARY_DIR) + " >/dev/null 2>&1";
  if (propcam::test::run_shell(reach).exit_code != 0) {
    std::fprintf(stderr, "security test: nobody cannot reach the build; running as uid %d\n", static_cast<int>(getuid()));
    return r;
  }
  r.drop = true;
  r.uid = user->pw_uid;
  r.gid = grp->gr_gid;
  r.prefix = prefix;
  return r;
}

// A scratch tree: the program's own folders, writable by the user it runs as,
// and a working directory, HOME and TMPDIR that are not its own (read-only to
// it, and any attempt to write there is reported by the trace).
struct Scratch {
  fs::path root;
  fs::path mine(const std::string& name, const RunAs& as) const {
    const fs::path dir = root / name;
    fs::create_directories(dir);
    if (as.drop && chown(dir.c_str(), as.uid, as.gid) != 0) throw std::runtime_error("chown " + dir.string());
    return dir;
  }
  fs::path theirs(const std::string& name) const {
    const fs::path dir = root / name;
    fs::create_directories(dir);
    return dir;
  }
};

Scratch make_scratch(const std::string& name) {
  Scratch s;
  s.root = fs::path(PROPCAM_BINARY_DIR) / "test-data" / "security" / name;
  fs::remove_all(s.root);
  fs::create_directories(s.root);
  // The way down from the build folder must be searchable by nobody.
  for (fs::path p = s.root; p != fs::path(PROPCAM_BINARY_DIR); p = p.parent_path())
    fs::permissions(p, fs::perms::others_exec | fs::perms::group_exec, fs::perm_options::add);
  return s;
}

// The environment the traced program gets: HOME and TMPDIR in the scratch
// tree, and no leak checks (LeakSanitizer cannot run under ptrace; the other
// suites check leaks).
std::string traced_command(const Scratch& s, const RunAs& as, const fs::path& trace, const std::string& program) {
  const std::string asan = std::getenv("ASAN_OPTIONS") ? std::getenv("ASAN_OPTIONS") : "";
  return "cd " + quote(s.theirs("cwd").string()) + " && exec env HOME=" + quote(s.theirs("home").string()) +
         " TMPDIR=" + quote(s.theirs("tmp").string()) + " ASAN_OPTIONS=" +
         quote(asan.empty() ? "detect_leaks=0" : asan + ":detect_leaks=0") +
         " strace -f -qq --seccomp-bpf -s 4096 -y -o " + quote(trace.string()) +
         " -e trace=socket,socketpair,bind,connect,listen,open,openat,openat2,creat,mkdir,mkdirat,rename,renameat,"
         "renameat2,link,linkat,symlink,symlinkat,unlink,unlinkat,rmdir,truncate,chmod,fchmodat,chown,lchown,"
         "fchownat,mknod,mknodat -- " +
         as.prefix + " " + program;
}

// One finding of a trace: the call and why it breaks the rule.
struct Violation {
  std::string why, line;
};

// The string arguments of a call, each with the folder it is relative to (a
// dirfd that strace -y printed as N</path> or AT_FDCWD</path>, else the
// working directory).
std::vector<fs::path> paths_of(const std::string& args, const fs::path& cwd) {
  std::vector<fs::path> out;
  static const std::regex arg(R"re((?:(?:\d+|AT_FDCWD)<([^>]*)>,\s*)?"((?:[^"\\]|\\.)*)")re");
  for (auto it = std::sregex_iterator(args.begin(), args.end(), arg); it != std::sregex_iterator(); ++it) {
    const std::string base = (*it)[1], name = (*it)[2];
    const fs::path p = fs::path(name).is_absolute() ? fs::path(name) : (base.empty() ? cwd : fs::path(base)) / name;
    out.push_back(p.lexically_normal());
  }
  return out;
}

bool under(const fs::path& p, const std::vector<fs::path>& roots) {
  for (const fs::path& r : roots) {
    const auto [end, _] = std::mismatch(r.begin(), r.end(), p.begin(), p.end());
    if (end == r.end()) return true;
  }
  return false;
}

// Every IP (or raw packet) socket, and every change to a file outside `roots`.
std::vector<Violation> check_trace(const fs::path& trace, const std::vector<fs::path>& roots, const fs::path& cwd) {
  std::vector<Violation> found;
  std::ifstream in(trace);
  std::string line;
  // "PID name(args" then ") = result" or " <unfinished ...>"; resumed halves
  // carry no arguments of interest.
  static const std::regex call(R"(^\d+\s+([a-z0-9_]+)\((.*)$)");
  static const std::regex ip(R"(\b(AF|PF)_(INET6?|PACKET)\b)");
  static const std::regex write_flags(R"(\b(O_WRONLY|O_RDWR|O_CREAT|O_TRUNC|O_APPEND|O_TMPFILE)\b)");
  while (std::getline(in, line)) {
    std::smatch m;
    if (!std::regex_match(line, m, call)) continue;
    const std::string name = m[1], args = m[2];
    if (name == "socket" || name == "socketpair" || name == "bind" || name == "connect" || name == "listen") {
      if (std::regex_search(args, ip)) found.push_back({"an IP socket", line});
      if (name != "bind") continue;  // a UNIX socket's bind makes a file
    }
    if (name == "open" || name == "openat" || name == "openat2") {
      if (!std::regex_search(args, write_flags)) continue;
    }
    std::vector<fs::path> paths = paths_of(args, cwd);
    if (name == "symlink" || name == "symlinkat") paths.erase(paths.begin());  // the link's text, not a file
    if (name == "bind") {
      // sun_path="..." only (an abstract socket has no file).
      static const std::regex sun(R"re(sun_path="([^"]*)")re");
      std::smatch s;
      paths.clear();
      if (std::regex_search(args, s, sun)) paths.push_back(fs::path(std::string(s[1])).lexically_normal());
    }
    for (const fs::path& p : paths)
      if (!under(p, roots) && !always_allowed(p)) found.push_back({"writes " + p.string(), line});
  }
  return found;
}

std::string describe(const std::vector<Violation>& v) {
  std::string out;
  for (std::size_t i = 0; i < v.size() && i < 40; ++i) out += v[i].why + "\n    " + v[i].line + "\n";
  if (v.size() > 40) out += "... " + std::to_string(v.size() - 40) + " more\n";
  return out;
}

// The trace must have seen the program at work, or an empty check proves nothing.
int count_lines_with(const fs::path& trace, const std::string& needle) {
  std::ifstream in(trace);
  std::string line;
  int n = 0;
  while (std::getline(in, line))
    if (line.find(needle) != std::string::npos) ++n;
  return n;
}

fs::path write_script(const fs::path& dir, const std::string& text) {
  const fs::path file = dir / "session.buttons";
  std::ofstream(file) << text;
  return file;
}

// Shoot, the cube at the first spot, the draft tier, render, export (as in
// appliance_run_test): every folder the appliance writes to gets written.
constexpr const char* kExportSession = R"(
at 1s press SHOOT
await placing 600s
+300ms press PREV
+300ms press PREV
+300ms press PREV
+300ms press OK
+300ms press OK
+300ms press PREV
+300ms press OK
await adjusting 1200s
+300ms hold OK 1200ms
await adjusting 300s
+300ms wait 0s
)";

// Shoot and see the photo analysed: frames and the still through propcamd.
constexpr const char* kShootSession = R"(
at 1s press SHOOT
await placing 600s
+300ms wait 0s
)";

TEST(ApplianceSecurity, RunsUnprivilegedOpensNoIpSocketAndWritesOnlyItsFolders) {
  if (!strace_works()) GTEST_SKIP() << "strace is not installed or cannot trace here (scripts/setup.sh installs it)";
  const RunAs as = unprivileged_user();
  const Scratch s = make_scratch("appliance");
  const fs::path data = s.mine("data", as), spool = s.mine("spool", as), snapshots = s.mine("snapshots", as),
                 usb = s.mine("usb", as);
  const fs::path script = write_script(s.theirs("input"), kExportSession);
  const fs::path trace = s.root / "trace.txt", log = s.root / "run.log";
  const std::string program = std::string(PROPCAM_CLI) + " run --json --threads 2 --board virtual --script " +
                              quote(script.string()) + " --data " + quote(data.string()) + " --spool " +
                              quote(spool.string()) + " --snapshots " + quote(snapshots.string()) + " --usb " +
                              quote(usb.string());
  const propcam::test::CliRun run =
      propcam::test::run_shell(traced_command(s, as, trace, program) + " 2>" + quote(log.string()));
  ASSERT_EQ(run.exit_code, 0) << read_text(log);
  const json summary = json::parse(run.out);
  EXPECT_EQ(summary["final_state"], "adjusting");
  // It did its work as that user: the composite is on the stick.
  int on_stick = 0;
  for (const auto& e : summary["exported"]) {
    const fs::path file = e.get<std::string>();
    EXPECT_TRUE(fs::exists(file)) << file;
    if (file.extension() == ".png" && fs::exists(file)) {
      ++on_stick;
      struct stat st {};
      ASSERT_EQ(stat(file.c_str(), &st), 0);
      EXPECT_EQ(st.st_uid, as.uid) << "written by the unprivileged user";
    }
  }
  EXPECT_EQ(on_stick, 1) << summary.dump(2);
  EXPECT_GT(count_lines_with(trace, usb.string()), 0) << "the trace saw the export";

  const std::vector<Violation> bad = check_trace(trace, {data, spool, snapshots, usb}, s.root / "cwd");
  EXPECT_TRUE(bad.empty()) << describe(bad);
}

// propcamd serves its socket in its runtime folder and the appliance takes
// frames and a still from it; both are traced.
TEST(ApplianceSecurity, PropcamdAndTheApplianceOnItRunUnprivilegedAndStayInTheirFolders) {
  if (!strace_works()) GTEST_SKIP() << "strace is not installed or cannot trace here (scripts/setup.sh installs it)";
  const RunAs as = unprivileged_user();
  const Scratch s = make_scratch("daemon");
  const fs::path run_dir = s.mine("run", as), data = s.mine("data", as), spool = s.mine("spool", as),
                 snapshots = s.mine("snapshots", as), usb = s.mine("usb", as);
  const fs::path socket = run_dir / "capture.sock";
  const fs::path daemon_trace = s.root / "propcamd.trace", daemon_log = s.root / "propcamd.log";
  const std::string camera = "replay:" + (kSource / "board/virtual/recordings/living_room").string();
  const std::string daemon_cmd = traced_command(s, as, daemon_trace,
                                                          std::string(PROPCAMD) + " --socket " + quote(socket.string()) +
                                                              " --camera " + quote(camera)) +
                                 " 2>" + quote(daemon_log.string());
  const pid_t daemon = fork();
  ASSERT_GE(daemon, 0);
  if (daemon == 0) {
    execl("/bin/sh", "sh", "-c", daemon_cmd.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // Bounded wait for the socket (not a timing assertion: it must come).
  for (int i = 0; i < 1200 && !fs::exists(socket); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const bool listening = fs::exists(socket);

  const fs::path script = write_script(s.theirs("input"), kShootSession);
  const fs::path trace = s.root / "propcam.trace", log = s.root / "run.log";
  const std::string program = std::string(PROPCAM_CLI) + " run --json --threads 2 --board virtual --script " +
                              quote(script.string()) + " --daemon " + quote(socket.string()) + " --data " +
                              quote(data.string()) + " --spool " + quote(spool.string()) + " --snapshots " +
                              quote(snapshots.string()) + " --usb " + quote(usb.string());
  propcam::test::CliRun run;
  if (listening) run = propcam::test::run_shell(traced_command(s, as, trace, program) + " 2>" + quote(log.string()));

  // SIGTERM to propcamd itself (strace's child), then strace ends with it.
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string stat = read_text(e.path() / "stat");
    const auto close = stat.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream rest(stat.substr(close + 2));
    char state = 0;
    long ppid = 0;
    rest >> state >> ppid;
    if (ppid == daemon) kill(static_cast<pid_t>(std::stol(e.path().filename().string())), SIGTERM);
  }
  int status = 0;
  waitpid(daemon, &status, 0);

  ASSERT_TRUE(listening) << read_text(daemon_log);
  ASSERT_EQ(run.exit_code, 0) << read_text(log) << "\npropcamd:\n" << read_text(daemon_log);
  EXPECT_EQ(json::parse(run.out)["final_state"], "placing");
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "propcamd stops cleanly\n" << read_text(daemon_log);
  EXPECT_GT(count_lines_with(daemon_trace, "bind("), 0) << "the trace saw propcamd's socket";
  EXPECT_GT(count_lines_with(trace, "connect("), 0) << "the trace saw the appliance reach propcamd";

  const std::vector<Violation> daemon_bad = check_trace(daemon_trace, {run_dir}, s.root / "cwd");
  EXPECT_TRUE(daemon_bad.empty()) << "propcamd:\n" << describe(daemon_bad);
  const std::vector<Violation> bad = check_trace(trace, {data, spool, snapshots, usb}, s.root / "cwd");
  EXPECT_TRUE(bad.empty()) << "propcam run:\n" << describe(bad);
}

}  // namespace
