#include "frictiond/testing/daemon_process.h"

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

namespace frictiond::testing {

namespace {

using Clock = std::chrono::steady_clock;

std::string Env(const char* name) {
  const char* v = std::getenv(name);
  return v ? std::string(v) : std::string();
}

std::string Tail(const std::string& s, std::size_t n) {
  return s.size() <= n ? s : "..." + s.substr(s.size() - n);
}

ExitStatus Decode(int status) {
  ExitStatus s;
  if (WIFEXITED(status)) {
    s.exited = true;
    s.code = WEXITSTATUS(status);
  } else if (WIFSIGNALED(status)) {
    s.signal = WTERMSIG(status);
  }
  return s;
}

}  // namespace

int FindFreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::runtime_error("FindFreePort: socket() failed");
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof addr;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    ::close(fd);
    throw std::runtime_error("FindFreePort: cannot bind 127.0.0.1:0");
  }
  const int port = ntohs(addr.sin_port);
  ::close(fd);
  return port;
}

std::string BinaryPath(const std::string& name) {
  const std::string dir = Env("FRICTIOND_BIN_DIR");
  if (dir.empty())
    throw std::runtime_error(
        "FRICTIOND_BIN_DIR is not set (run through ctest, or set it to "
        "build/bin)");
  const std::string path = dir + "/" + name;
  if (::access(path.c_str(), X_OK) != 0)
    throw std::runtime_error(path + ": not an executable (build target '" +
                             name + "' first)");
  return path;
}

std::string SourceDir() {
  const std::string dir = Env("FRICTIOND_SOURCE_DIR");
  if (dir.empty())
    throw std::runtime_error(
        "FRICTIOND_SOURCE_DIR is not set (run through ctest, or set it to the "
        "repository root)");
  return dir;
}

// --- TempDir ---------------------------------------------------------------

TempDir::TempDir(const std::string& prefix) {
  std::string base = Env("TMPDIR");
  if (base.empty()) base = "/tmp";
  std::string templ = base + "/" + prefix + ".XXXXXX";
  std::vector<char> buf(templ.begin(), templ.end());
  buf.push_back('\0');
  if (::mkdtemp(buf.data()) == nullptr)
    throw std::runtime_error("TempDir: mkdtemp(" + templ + ") failed");
  path_ = buf.data();
}

TempDir::~TempDir() {
  if (path_.empty()) return;
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

TempDir::TempDir(TempDir&& other) noexcept : path_(std::move(other.path_)) {
  other.path_.clear();
}

TempDir& TempDir::operator=(TempDir&& other) noexcept {
  if (this != &other) {
    if (!path_.empty()) {
      std::error_code ec;
      std::filesystem::remove_all(path_, ec);
    }
    path_ = std::move(other.path_);
    other.path_.clear();
  }
  return *this;
}

// --- ExitStatus ------------------------------------------------------------

std::string ExitStatus::ToString() const {
  std::string s = timed_out ? "timed out, then " : "";
  if (exited) return s + "exit " + std::to_string(code);
  if (signal != 0) return s + "signal " + std::to_string(signal);
  return s + "unknown";
}

// --- DaemonProcess ---------------------------------------------------------

DaemonProcess::DaemonProcess(DaemonOptions options)
    : options_(std::move(options)) {
  if (options_.db.empty())
    throw std::invalid_argument("DaemonOptions.db: empty (give a file path)");
  if (options_.binary.empty()) options_.binary = BinaryPath("frictiond");
  if (options_.log_path.empty()) {
    if (options_.db.find("://") != std::string::npos)
      throw std::invalid_argument(
          "DaemonOptions.log_path: required when db is a URL (" + options_.db +
          ")");
    options_.log_path = options_.db + ".log";
  }
}

DaemonProcess::~DaemonProcess() {
  if (running()) Kill();
}

std::string DaemonProcess::base_url() const {
  return "http://" + options_.bind + ":" + std::to_string(port_);
}

std::string DaemonProcess::ReadLog() const {
  std::ifstream in(options_.log_path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::unique_ptr<httplib::Client> DaemonProcess::MakeClient(
    double read_timeout_s, bool keep_alive) const {
  return MakeClientWithToken(
      options_.operator_token, read_timeout_s, keep_alive);
}

std::unique_ptr<httplib::Client> DaemonProcess::MakeClientWithToken(
    const std::string& token, double read_timeout_s, bool keep_alive) const {
  auto client = std::make_unique<httplib::Client>(options_.bind, port_);
  client->set_connection_timeout(2, 0);
  const auto whole = static_cast<time_t>(read_timeout_s);
  const auto micros =
      static_cast<time_t>((read_timeout_s - static_cast<double>(whole)) * 1e6);
  client->set_read_timeout(whole, micros);
  client->set_write_timeout(whole > 0 ? whole : 1, 0);
  client->set_keep_alive(keep_alive);
  if (!token.empty()) client->set_bearer_token_auth(token);
  return client;
}

void DaemonProcess::Start() {
  if (running())
    throw std::logic_error("DaemonProcess::Start: already running");
  std::string why;
  const int attempts = options_.port == 0 ? 3 : 1;
  for (int attempt = 0; attempt < attempts; ++attempt) {
    if (SpawnAndWait(&why)) return;
    // Only a lost race for the port is worth another try.
    if (why.find("cannot bind") == std::string::npos) break;
  }
  throw std::runtime_error("frictiond did not start: " + why + "\n--- log (" +
                           options_.log_path + ") ---\n" +
                           Tail(ReadLog(), 4000));
}

bool DaemonProcess::SpawnAndWait(std::string* why) {
  port_ = options_.port != 0 ? options_.port : FindFreePort();
  // Everything the child needs is prepared before fork(): after it, only
  // async-signal-safe calls happen in the child.
  std::vector<std::string> args = {
      options_.binary, "--db", options_.db, "--port", std::to_string(port_)};
  if (!options_.bind.empty())
    args.insert(args.end(), {"--bind", options_.bind});
  if (!options_.data.empty())
    args.insert(args.end(), {"--data", options_.data});
  if (!options_.lcm.empty()) args.insert(args.end(), {"--lcm", options_.lcm});
  if (options_.threads > 0)
    args.insert(args.end(), {"--threads", std::to_string(options_.threads)});
  if (options_.max_body_mb > 0)
    args.insert(args.end(),
                {"--max-body-mb", std::to_string(options_.max_body_mb)});
  if (!options_.operator_token.empty())
    args.insert(args.end(), {"--bootstrap-token", options_.operator_token});
  args.insert(
      args.end(), options_.extra_args.begin(), options_.extra_args.end());
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  const std::size_t log_start = ReadLog().size();
  const int log_fd = ::open(options_.log_path.c_str(),
                            O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC,
                            0644);
  if (log_fd < 0) {
    *why = "cannot open log " + options_.log_path;
    return false;
  }
  const int null_fd = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  const pid_t parent = ::getpid();
  const bool pdeath = options_.kill_with_parent;
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(log_fd);
    if (null_fd >= 0) ::close(null_fd);
    *why = "fork() failed";
    return false;
  }
  if (pid == 0) {
    if (pdeath) {
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (::getppid() != parent) ::_exit(127);
    }
    // Signals blocked or ignored by the test process are inherited: reset.
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::signal(SIGPIPE, SIG_DFL);
    if (null_fd >= 0) ::dup2(null_fd, 0);
    ::dup2(log_fd, 1);
    ::dup2(log_fd, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ::close(log_fd);
  if (null_fd >= 0) ::close(null_fd);
  pid_ = pid;

  const auto deadline =
      Clock::now() +
      std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(options_.start_timeout_s));
  httplib::Client probe(options_.bind, port_);
  probe.set_connection_timeout(0, 200000);
  probe.set_read_timeout(1, 0);
  while (Clock::now() < deadline) {
    int status = 0;
    const pid_t r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_) {
      pid_ = -1;
      last_ = Decode(status);
      const std::string log = ReadLog();
      const std::string this_run =
          log.size() > log_start ? log.substr(log_start) : "";
      *why = "it exited during start-up (" + last_.ToString() + ")";
      if (this_run.find("cannot bind") != std::string::npos)
        *why += ": cannot bind port " + std::to_string(port_);
      return false;
    }
    if (auto res = probe.Get("/healthz"); res && res->status == 200)
      return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  *why = "GET /healthz did not answer 200 within " +
         std::to_string(options_.start_timeout_s) + " s";
  Kill();
  return false;
}

ExitStatus DaemonProcess::Reap(int signal, double timeout_s) {
  if (!running()) return last_;
  ::kill(pid_, signal);
  const auto deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(
                         std::chrono::duration<double>(timeout_s));
  bool timed_out = false;
  for (;;) {
    int status = 0;
    const pid_t r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_ || (r < 0 && errno != EINTR)) {
      last_ = r == pid_ ? Decode(status) : ExitStatus{};
      last_.timed_out = timed_out;
      pid_ = -1;
      return last_;
    }
    if (!timed_out && Clock::now() > deadline) {
      timed_out = true;
      ::kill(pid_, SIGKILL);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

ExitStatus DaemonProcess::Stop(int signal, double timeout_s) {
  return Reap(signal, timeout_s);
}

ExitStatus DaemonProcess::Kill() { return Reap(SIGKILL, 30.0); }

// --- files ------------------------------------------------------------------

std::uint64_t HashFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return 0;
  std::uint64_t h = 14695981039346656037ull;
  char buf[1 << 16];
  while (in) {
    in.read(buf, sizeof buf);
    const std::streamsize n = in.gcount();
    for (std::streamsize i = 0; i < n; ++i) {
      h ^= static_cast<unsigned char>(buf[i]);
      h *= 1099511628211ull;
    }
  }
  return h;
}

std::vector<std::uint64_t> DbFingerprint(const std::string& db) {
  return {HashFile(db), HashFile(db + "-wal"), HashFile(db + "-shm")};
}

}  // namespace frictiond::testing
