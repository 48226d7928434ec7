// peridot run when a file cannot be written: a full disk (the shell's `ulimit -f`, with SIGXFSZ
// ignored, so writes past it fail with EFBIG as they would with ENOSPC; or /dev/full), a DDS
// participant that cannot start, and rank 1 of 2 unable to write its VTU piece. Each must exit 1
// naming the file, keep whole CSV rows, and leave no .tmp behind. Every process is bounded by
// `timeout` and reaped; MPI traffic stays on loopback.
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>
#include "../support/cli_run.hpp"
#include "../support/mpirun.hpp"
#include "../support/no_tmp.hpp"

namespace fs = std::filesystem;

namespace {

fs::path temp(const std::string& name) { return cli_run::temp("peridot_full_disk_", name); }

// A small PMB plate with the given output section; 400 steps at most.
fs::path deck(const std::string& name, const std::string& output) {
  const fs::path file = temp(name + ".yaml");
  std::ofstream(file) << "name: disk\n"
                         "dimension: 2\n"
                         "geometry: {body: {rectangle: {min: [0, 0], max: [0.01, 0.004]}}}\n"
                         "discretization: {spacing: 2.0e-4, horizon_factor: 3}\n"
                         "material: {model: pmb, kinematics: plane_stress, youngs_modulus: 72.0e9, density: 2440.0, "
                         "fracture_energy: 3.8}\n"
                         "boundaries:\n"
                         "  - {name: top, type: traction, region: {layer: {side: +y, count: 1}}, value: [0.0, 1.0e6]}\n"
                         "solver: {type: explicit, end_time: 1.0e-5}\n"
                      << "output: " << output << "\n";
  return file;
}

// `peridot run` in a shell whose files may not grow past `blocks` x 512 bytes (dash's unit).
cli_run::Result run_limited(const fs::path& deck_file, const fs::path& out, int blocks) {
  return cli_run::run("sh -c \"trap '' XFSZ; ulimit -f " + std::to_string(blocks) + "; exec " + std::string(PERIDOT_EXE) + " run " +
                          deck_file.string() + " --quiet --threads 1 --out " + out.string() + "\"",
                      temp("err"), "");
}


}  // namespace

TEST_CASE("a run whose history CSV meets a full disk exits 1 naming the file, and the rows written are whole") {
  const auto out = temp("csv");
  fs::remove_all(out);
  const auto r = run_limited(deck("csv", "{csv: {every: 1}}"), out, 16);  // 8 KiB: tens of rows of hundreds
  INFO(r.err);
  CHECK(r.code == 1);
  const auto file = out / "disk_history.csv";
  CHECK(r.err.find(file.string()) != std::string::npos);
  std::ifstream in(file, std::ios::binary);
  const std::string all{std::istreambuf_iterator<char>(in), {}};
  REQUIRE_FALSE(all.empty());
  CHECK(all.back() == '\n');
  std::stringstream ss(all);
  std::string header, line;
  std::getline(ss, header);
  const auto columns = std::count(header.begin(), header.end(), ',');
  std::size_t rows = 0;
  while (std::getline(ss, line)) {
    INFO("row " << rows << ": " << line);
    CHECK(std::count(line.begin(), line.end(), ',') == columns);
    CHECK(line.rfind(std::to_string(rows) + ",", 0) == 0);  // step k in row k: none lost or torn
    ++rows;
  }
  CHECK(rows > 5);
  CHECK(no_tmp::left_in(out));
  fs::remove_all(out);
}

TEST_CASE("a run whose VTU meets a full disk exits 1 naming the file and leaves no .tmp") {
  const auto out = temp("vtu");
  fs::remove_all(out);
  const auto r = run_limited(deck("vtu", "{vtu: {every: 100}}"), out, 16);
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK(r.err.find((out / "disk_0000000.vtu").string()) != std::string::npos);
  CHECK(no_tmp::left_in(out));
  fs::remove_all(out);
}

TEST_CASE("a run whose DDS participant cannot start exits 1 before it creates its output directory") {
  const auto out = temp("dds");
  fs::remove_all(out);
  // A configuration file that does not exist: Cyclone refuses to create the domain.
  const auto r = cli_run::run("env CYCLONEDDS_URI=file:///nonexistent/peridot-dds.xml " + std::string(PERIDOT_EXE), temp("dds.err"),
                              "run " + deck("dds", "{csv: {every: 10}, dds: {every: 10}}").string() + " --quiet --out " + out.string());
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK(r.err.find("DDS") != std::string::npos);
  CHECK_FALSE(fs::exists(out));
}

TEST_CASE("rank 1 of 2 unable to write its VTU piece ends the run with exit 1, naming the file, with no .tmp left") {
  const auto out = temp("piece");
  fs::remove_all(out);
  fs::create_directories(out);
  // Rank 1's first piece is written through its .tmp name: make that name lead to a full device.
  const auto tmp = out / "disk_0000000_1.vtu.tmp";
  fs::create_symlink("/dev/full", tmp);
  const auto r = cli_run::run(mpirun(2), temp("piece.err"), "run " + deck("piece", "{vtu: {every: 100}}").string() +
                                                                " --quiet --threads 1 --out " + out.string());
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK(r.err.find("rank 1") != std::string::npos);
  CHECK(r.err.find((out / "disk_0000000_1.vtu").string()) != std::string::npos);
  CHECK_FALSE(fs::is_symlink(tmp));
  CHECK(no_tmp::left_in(out));
  fs::remove_all(out);
}
