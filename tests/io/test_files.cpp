// A full disk never passes silently and never leaves a torn file. The disk is made full for one
// child process with RLIMIT_FSIZE (writes past the limit fail with EFBIG, as ENOSPC would on a
// full file system, and the bytes that fit are really written), or is /dev/full (ENOSPC).
#include <catch2/catch.hpp>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>
#include <peridot/run_record.hpp>

#include "../support/no_tmp.hpp"
import peridot.io;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

fs::path temp(const std::string& name) { return fs::temp_directory_path() / ("peridot_files_" + std::to_string(getpid()) + "_" + name); }

// Runs `write` in a child whose files may not grow past `limit` bytes. The child exits 0 when
// `write` threw an error naming `file`, 1 when it threw one that does not, 2 when it did not
// throw at all.
int with_disk_limit(rlim_t limit, const fs::path& file, const std::function<void()>& write) {
  const pid_t child = fork();
  REQUIRE(child >= 0);
  if (child == 0) {
    signal(SIGXFSZ, SIG_IGN);  // a write past the limit fails with EFBIG instead of killing
    const rlimit r{limit, limit};
    setrlimit(RLIMIT_FSIZE, &r);
    int code = 2;
    try {
      write();
    } catch (const std::exception& e) {
      code = std::string(e.what()).find(file.string()) != std::string::npos ? 0 : 1;
    }
    _exit(code);  // never back into Catch
  }
  int status = 0;
  waitpid(child, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::vector<std::string> lines_of(const fs::path& file, bool& ends_with_newline) {
  std::ifstream in(file, std::ios::binary);
  const std::string all{std::istreambuf_iterator<char>(in), {}};
  ends_with_newline = all.empty() || all.back() == '\n';
  std::vector<std::string> lines;
  std::stringstream ss(all);
  for (std::string line; std::getline(ss, line);) lines.push_back(line);
  return lines;
}


}  // namespace

TEST_CASE("a history CSV that hits a full disk throws naming the file and keeps only whole rows") {
  const auto dir = temp("csv");
  fs::create_directories(dir);
  const auto file = dir / "run_history.csv";
  // 3000 bytes hold the header and some rows; the row that crosses the limit is cut off again.
  CHECK(with_disk_limit(3000, file, [&] {
          HistoryCsv csv(file);
          for (std::size_t k = 0; k < 1000; ++k) {
            RunRecord r;
            r.step = k;
            r.time = 1e-9 * double(k);
            r.kinetic_energy = 1.0 / double(k + 3);
            csv.append(r);
          }
        }) == 0);
  bool newline = false;
  const auto lines = lines_of(file, newline);
  CHECK(newline);
  REQUIRE(lines.size() > 3);
  CHECK(lines.front() == HistoryCsv::header());
  const auto columns = std::count(lines.front().begin(), lines.front().end(), ',');
  for (std::size_t k = 1; k < lines.size(); ++k) {
    INFO("row " << k << ": " << lines[k]);
    CHECK(std::count(lines[k].begin(), lines[k].end(), ',') == columns);
    CHECK(lines[k].rfind(std::to_string(k - 1) + ",", 0) == 0);  // rows in order, none skipped
  }
  CHECK(fs::file_size(file) <= 3000);
  fs::remove_all(dir);
}

TEST_CASE("a record file on /dev/full throws naming it at the first record") {
  RecordFile f("/dev/full");
  CHECK_THROWS_WITH(f.append("step,time\n"), Catch::Contains("/dev/full") && Catch::Contains("No space left"));
}

TEST_CASE("an atomic write that hits a full disk keeps the previous file, leaves no .tmp and names the file") {
  const auto dir = temp("atomic");
  fs::create_directories(dir);
  const auto file = dir / "table.csv";
  write_file_atomically(file, {"old content\n"});
  CHECK(with_disk_limit(100, file, [&] { write_file_atomically(file, {std::string(1000, 'x'), "\n"}); }) == 0);
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  CHECK(line == "old content");
  CHECK(no_tmp::left_in(dir));
  fs::remove_all(dir);
}

TEST_CASE("a VTU that hits a full disk names the file and leaves no .tmp") {
  const auto dir = temp("vtu");
  fs::create_directories(dir);
  const auto pc = lattice(rectangle({0, 0, 0}, {0.01, 0.01, 0}), {.spacing = 1e-4});
  std::vector<double> a(pc.size(), 0.5);
  const NamedField fields[] = {{"damage", 1, {a, {}, {}}}};
  const auto file = dir / "x.vtu";
  CHECK(with_disk_limit(16384, file, [&] { write_vtu(file, pc, fields); }) == 0);
  CHECK_FALSE(fs::exists(file));
  CHECK(no_tmp::left_in(dir));
  fs::remove_all(dir);
}
