// PETSc started in a process that mpirun did not launch (every serial run and in-process test
// that solves on PETSc): a one-rank world of its own, with no helper process to start or reap.
#include <catch2/catch.hpp>

#include <dirent.h>
#include <unistd.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>
import peridot.parallel;

namespace {

// The names of this process's direct children, from /proc/<pid>/stat ("pid (comm) state ppid").
std::vector<std::string> children() {
  std::vector<std::string> names;
  DIR* d = opendir("/proc");
  REQUIRE(d != nullptr);
  while (const dirent* e = readdir(d)) {
    const std::string pid = e->d_name;
    if (pid.empty() || pid.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream in("/proc/" + pid + "/stat");
    std::string stat;
    if (!std::getline(in, stat)) continue;  // it ended meanwhile
    const auto open = stat.find('('), close = stat.rfind(')');
    if (open == std::string::npos || close == std::string::npos) continue;
    std::istringstream rest(stat.substr(close + 2));
    char state = 0;
    long ppid = 0;
    rest >> state >> ppid;
    if (ppid == long(getpid())) names.push_back(stat.substr(open + 1, close - open - 1));
  }
  closedir(d);
  return names;
}

}  // namespace

TEST_CASE("PETSc started outside mpirun is a one-rank world and leaves no helper process running (no orted)") {
  REQUIRE_FALSE(peridot::parallel::launched_by_mpirun());
  peridot::parallel::start();
  CHECK(peridot::parallel::started());
  CHECK(peridot::parallel::ranks() == 1);
  CHECK(peridot::parallel::rank() == 0);
  std::string kids;
  for (const auto& n : children()) kids += n + " ";
  INFO("children: " << kids);
  CHECK(kids.empty());
}
