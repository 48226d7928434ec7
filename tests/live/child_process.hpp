// A child process for the multi-process DDS tests: started with posix_spawn,
// stdout and stderr captured, and always reaped: wait() kills it at its
// deadline and the destructor kills and reaps one that is still running.
#pragma once
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

extern char** environ;

struct ChildResult {
  int exit_code = -1;  // -1 when killed by a signal
  bool timed_out = false;
  std::string out, err;
};

class ChildProcess {
 public:
  // argv[0] is the executable path; env entries "NAME=value" replace inherited ones.
  ChildProcess(const std::vector<std::string>& argv, const std::vector<std::string>& env) {
    int out[2], err[2];
    // O_CLOEXEC: a later child must not inherit these ends, or EOF never comes.
    if (pipe2(out, O_CLOEXEC) != 0 || pipe2(err, O_CLOEXEC) != 0) throw std::runtime_error("pipe2 failed");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&actions, err[1], STDERR_FILENO);

    std::vector<std::string> envs = env;
    for (char** e = environ; *e; ++e) {
      const std::string entry = *e;
      const auto name = entry.substr(0, entry.find('=') + 1);
      bool replaced = false;
      for (const auto& o : env) replaced = replaced || o.rfind(name, 0) == 0;
      if (!replaced) envs.push_back(entry);
    }
    std::vector<char*> cargv, cenv;
    for (const auto& a : argv) cargv.push_back(const_cast<char*>(a.c_str()));
    for (const auto& e : envs) cenv.push_back(const_cast<char*>(e.c_str()));
    cargv.push_back(nullptr);
    cenv.push_back(nullptr);
    const int rc = posix_spawn(&pid_, argv.at(0).c_str(), &actions, nullptr, cargv.data(), cenv.data());
    posix_spawn_file_actions_destroy(&actions);
    close(out[1]);
    close(err[1]);
    out_ = out[0];
    err_ = err[0];
    if (rc != 0) {
      pid_ = -1;
      throw std::runtime_error("posix_spawn " + argv[0] + ": " + std::strerror(rc));
    }
  }

  ~ChildProcess() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
    if (out_ >= 0) close(out_);
    if (err_ >= 0) close(err_);
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  // Sends a signal to the running child (SIGTERM, SIGINT: a graceful stop).
  void signal(int sig) const {
    if (pid_ > 0) kill(pid_, sig);
  }
  // Collects output until the child exits; past `timeout` it is killed.
  ChildResult wait(std::chrono::milliseconds timeout) {
    ChildResult r;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    bool out_open = true, err_open = true;
    while (out_open || err_open) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) {
        r.timed_out = true;
        kill(pid_, SIGKILL);
        break;
      }
      pollfd fds[2] = {{out_open ? out_ : -1, POLLIN, 0}, {err_open ? err_ : -1, POLLIN, 0}};
      if (poll(fds, 2, int(std::min<long long>(left.count(), 100))) < 0 && errno != EINTR) break;
      out_open = out_open && drain(fds[0], out_, r.out);
      err_open = err_open && drain(fds[1], err_, r.err);
    }
    int status = 0;
    waitpid(pid_, &status, 0);  // output closed (exit) or killed: this returns promptly
    pid_ = -1;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
  }

 private:
  // Appends what is readable; false at end of file.
  static bool drain(const pollfd& p, int fd, std::string& into) {
    if (!(p.revents & (POLLIN | POLLHUP | POLLERR))) return true;
    char buf[4096];
    const ssize_t n = read(fd, buf, sizeof buf);
    if (n > 0) into.append(buf, std::size_t(n));
    return n > 0 || (n < 0 && errno == EINTR);
  }

  pid_t pid_ = -1;
  int out_ = -1, err_ = -1;
};
