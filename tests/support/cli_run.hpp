#pragma once
// Runs the peridot CLI as a child process with a time bound, for the app tests.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace cli_run {

struct Result {
  int code;         // exit code; -1 when killed
  std::string err;  // stderr
};

// Per-process temporary names: ctest runs the test cases of a file in parallel.
inline std::filesystem::path temp(const std::string& prefix, const std::string& name) {
  return std::filesystem::temp_directory_path() / (prefix + std::to_string(getpid()) + "_" + name);
}

// `exe args` under `timeout 120`; stdout is discarded, stderr captured through err_file.
inline Result run(const std::string& exe, const std::filesystem::path& err_file, const std::string& args) {
  const std::string cmd = "timeout 120 " + exe + " " + args + " > /dev/null 2> " + err_file.string();
  const int status = std::system(cmd.c_str());
  std::ifstream in(err_file);
  std::stringstream ss;
  ss << in.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ss.str()};
}

}  // namespace cli_run
