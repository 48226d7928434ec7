#pragma once
// Runs the peridot CLI as a child process with a time bound, for the app tests.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

namespace cli_run {

// Every path temp() named, removed when the test process exits, pass or fail (a failing case
// has printed the run's stderr by then): the runs' output folders would otherwise pile up in /tmp.
struct TempPaths {
  std::vector<std::filesystem::path> paths;
  ~TempPaths() {
    for (const auto& p : paths) {
      std::error_code ignored;
      std::filesystem::remove_all(p, ignored);
    }
  }
};
inline TempPaths& temp_paths() {
  static TempPaths paths;
  return paths;
}

struct Result {
  int code;         // exit code; -1 when killed
  std::string err;  // stderr
};

// Per-process temporary names: ctest runs the test cases of a file in parallel.
inline std::filesystem::path temp(const std::string& prefix, const std::string& name) {
  auto path = std::filesystem::temp_directory_path() / (prefix + std::to_string(getpid()) + "_" + name);
  temp_paths().paths.push_back(path);
  return path;
}

// `exe args` under `timeout 120`; stdout goes to out_file (discarded by default), stderr is
// captured through err_file.
inline Result run(const std::string& exe, const std::filesystem::path& err_file, const std::string& args,
                  const std::filesystem::path& out_file = "/dev/null") {
  const std::string cmd = "timeout 120 " + exe + " " + args + " > " + out_file.string() + " 2> " + err_file.string();
  const int status = std::system(cmd.c_str());
  std::ifstream in(err_file);
  std::stringstream ss;
  ss << in.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ss.str()};
}

}  // namespace cli_run
