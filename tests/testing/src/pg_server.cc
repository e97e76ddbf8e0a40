#include "frictiond/testing/pg_server.h"

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <fcntl.h>
#include <grp.h>
#include <pwd.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include "frictiond/testing/daemon_process.h"

namespace frictiond::testing {

namespace {

std::string Env(const char* name) {
  const char* v = std::getenv(name);
  return v ? std::string(v) : std::string();
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

std::string Tail(const std::string& s, std::size_t n) {
  return s.size() <= n ? s : "..." + s.substr(s.size() - n);
}

/// In a forked child: become uid/gid (when different) and exec argv with
/// stdout+stderr to `out_fd`. Never returns.
[[noreturn]] void ExecAs(const std::vector<std::string>& argv,
                         int out_fd,
                         uid_t uid,
                         gid_t gid,
                         int death_signal) {
  if (out_fd >= 0) {
    ::dup2(out_fd, 1);
    ::dup2(out_fd, 2);
  }
  const int devnull = ::open("/dev/null", O_RDONLY);
  if (devnull >= 0) ::dup2(devnull, 0);
  if (::geteuid() != uid) {
    if (::setgroups(0, nullptr) != 0 || ::setgid(gid) != 0 ||
        ::setuid(uid) != 0)
      ::_exit(126);
  }
  if (death_signal) ::prctl(PR_SET_PDEATHSIG, death_signal);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  ::execv(args[0], args.data());
  ::_exit(127);
}

}  // namespace

PgServer::PgServer() {
  uid_ = ::geteuid();
  gid_ = ::getegid();
}

PgServer::~PgServer() {
  Stop();
  if (!dir_.empty()) {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
}

std::string PgServer::BinDir() {
  std::string dir = Env("FRICTIOND_PG_BIN");
  if (dir.empty()) dir = "/usr/lib/postgresql/15/bin";
  for (const char* b : {"initdb", "postgres", "psql", "pg_isready"}) {
    if (::access((dir + "/" + b).c_str(), X_OK) != 0) return "";
  }
  return dir;
}

int PgServer::Run(const std::vector<std::string>& argv,
                  std::string* output) const {
  const std::string out_path = dir_ + "/cmd.out";
  const int fd =
      ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error("PgServer: cannot write " + out_path);
  if (::fchown(fd, uid_, gid_) != 0) {
    // Harmless: the child only needs the inherited descriptor.
  }
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fd);
    throw std::runtime_error("PgServer: fork failed");
  }
  if (pid == 0) ExecAs(argv, fd, uid_, gid_, 0);
  ::close(fd);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (output) *output = ReadFile(out_path);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

void PgServer::Start() {
  if (running()) return;
  const std::string bin = BinDir();
  if (bin.empty())
    throw std::runtime_error(
        "PgServer: PostgreSQL 15 binaries not found (install Debian "
        "package 'postgresql')");
  if (dir_.empty()) {
    std::string base = Env("TMPDIR");
    if (base.empty()) base = "/tmp";
    std::string templ = base + "/frictiond_pg.XXXXXX";
    std::vector<char> buf(templ.begin(), templ.end());
    buf.push_back('\0');
    if (::mkdtemp(buf.data()) == nullptr)
      throw std::runtime_error("PgServer: mkdtemp(" + templ + ") failed");
    dir_ = buf.data();
    if (::geteuid() == 0) {
      // initdb and postgres refuse to run as root.
      const passwd* pw = ::getpwnam("postgres");
      if (!pw)
        throw std::runtime_error(
            "PgServer: running as root and there is no 'postgres' user "
            "(created by the Debian postgresql package)");
      uid_ = pw->pw_uid;
      gid_ = pw->pw_gid;
      if (::chown(dir_.c_str(), uid_, gid_) != 0)
        throw std::runtime_error("PgServer: cannot chown " + dir_);
    }
    std::filesystem::create_directory(dir_ + "/sock");
    if (::chown((dir_ + "/sock").c_str(), uid_, gid_) != 0)
      throw std::runtime_error("PgServer: cannot chown " + dir_ + "/sock");
  }
  if (!initialised_) {
    std::string out;
    const int rc = Run({bin + "/initdb",
                        "-D",
                        dir_ + "/data",
                        "-U",
                        "postgres",
                        "-A",
                        "trust",
                        "-E",
                        "UTF8",
                        "--locale=C",
                        "--no-instructions",
                        // The server runs with fsync on; the initial files
                        // of a throw-away cluster need not be synced.
                        "--no-sync"},
                       &out);
    if (rc != 0)
      throw std::runtime_error("PgServer: initdb failed (exit " +
                               std::to_string(rc) + "): " + Tail(out, 2000));
    initialised_ = true;
  }
  for (int attempt = 0; attempt < 5; ++attempt) {
    if (port_ == 0 || attempt > 0) port_ = FindFreePort();
    const std::string log = dir_ + "/server.log";
    const int fd =
        ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (fd < 0) throw std::runtime_error("PgServer: cannot write " + log);
    const pid_t pid = ::fork();
    if (pid < 0) {
      ::close(fd);
      throw std::runtime_error("PgServer: fork failed");
    }
    if (pid == 0) {
      ExecAs({bin + "/postgres",
              "-D",
              dir_ + "/data",
              "-p",
              std::to_string(port_),
              "-c",
              "listen_addresses=127.0.0.1",
              "-c",
              "unix_socket_directories=" + dir_ + "/sock",
              "-c",
              "fsync=on",
              "-c",
              "max_connections=200",
              "-c",
              "shared_buffers=32MB"},
             fd,
             uid_,
             gid_,
             SIGINT);
    }
    ::close(fd);
    pid_ = pid;
    try {
      WaitReady(30.0);
      return;
    } catch (const std::exception&) {
      int status = 0;
      if (pid_ < 0) continue;  // exited (port taken?): try another port
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, &status, 0);
      pid_ = -1;
      throw std::runtime_error("PgServer: server did not become ready: " +
                               Tail(ReadLog(), 2000));
    }
  }
  throw std::runtime_error("PgServer: server did not start: " +
                           Tail(ReadLog(), 2000));
}

void PgServer::WaitReady(double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration<double>(timeout_s);
  const std::string bin = BinDir();
  while (std::chrono::steady_clock::now() < deadline) {
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      throw std::runtime_error("postgres exited");
    }
    if (Run({bin + "/pg_isready",
             "-q",
             "-h",
             "127.0.0.1",
             "-p",
             std::to_string(port_)},
            nullptr) == 0)
      return;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  throw std::runtime_error("timeout");
}

void PgServer::Stop() {
  if (pid_ <= 0) return;
  ::kill(pid_, SIGINT);  // fast shutdown
  int status = 0;
  while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  pid_ = -1;
}

void PgServer::Crash() {
  if (pid_ <= 0) return;
  ::kill(pid_, SIGQUIT);  // immediate shutdown
  int status = 0;
  while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  pid_ = -1;
}

std::string PgServer::Url(const std::string& db) const {
  return "postgresql://postgres@127.0.0.1:" + std::to_string(port_) + "/" + db;
}

std::string PgServer::Psql(const std::string& sql, const std::string& db) {
  return Psql(std::vector<std::string>{sql}, db);
}

std::string PgServer::Psql(const std::vector<std::string>& commands,
                           const std::string& db) {
  std::vector<std::string> argv = {BinDir() + "/psql",
                                   "-X",
                                   "-q",
                                   "-A",
                                   "-t",
                                   "-v",
                                   "ON_ERROR_STOP=1",
                                   "-h",
                                   "127.0.0.1",
                                   "-p",
                                   std::to_string(port_),
                                   "-U",
                                   "postgres",
                                   "-d",
                                   db};
  std::string all;
  for (const std::string& c : commands) {
    argv.push_back("-c");
    argv.push_back(c);
    all += (all.empty() ? "" : "; ") + c;
  }
  std::string out;
  const int rc = Run(argv, &out);
  if (rc != 0)
    throw std::runtime_error("PgServer: psql failed on '" + all +
                             "': " + Tail(out, 1000));
  return out;
}

std::string PgServer::CreateDatabase(const std::string& name) {
  // Separate -c commands: CREATE DATABASE cannot run in a transaction.
  Psql(std::vector<std::string>{
      "DROP DATABASE IF EXISTS \"" + name + "\" WITH (FORCE)",
      "CREATE DATABASE \"" + name + "\""});
  return Url(name);
}

std::string PgServer::ReadLog() const { return ReadFile(dir_ + "/server.log"); }

}  // namespace frictiond::testing
