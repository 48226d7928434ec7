#include <catch2/catch.hpp>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>
import peridot.problem;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

// Per-process names: ctest runs the test cases of this file in parallel.
fs::path temp(const std::string& name) { return fs::temp_directory_path() / ("peridot_ckpt_" + std::to_string(getpid()) + "_" + name); }

// A checkpoint whose every value is set, including ones a text format would round.
Checkpoint sample(std::size_t n, std::size_t bonds, double seed) {
  Checkpoint c;
  c.deck_name = "sample_deck";
  c.deck_hash = 0xfedcba9876543210ull;
  c.dim = 2;
  c.points = n;
  c.bonds = bonds;
  c.dt = 1.0 / 3.0 * 1e-7;
  c.scheme = "central_difference";
  c.step = 12345;
  c.time = double(c.step) * c.dt;
  for (int k = 0; k < 3; ++k)
    for (std::size_t i = 0; i < n; ++i) {
      c.u[k].push_back(seed * (0.1 + double(i)) / (7.0 + k));
      c.v[k].push_back(-seed * std::numeric_limits<double>::denorm_min() * double(i + k));
      c.f[k].push_back(seed * 1e300 / (1.0 + double(i * 3 + k)));
    }
  for (std::size_t b = 0; b < bonds; ++b) c.bond_state.push_back(std::uint8_t(b % 3 != 0));
  c.external_work = seed * 0.1;
  c.broken = bonds / 3;
  return c;
}

void require_equal(const Checkpoint& a, const Checkpoint& b) {
  CHECK(a.deck_name == b.deck_name);
  CHECK(a.deck_hash == b.deck_hash);
  CHECK(a.dim == b.dim);
  CHECK(a.points == b.points);
  CHECK(a.bonds == b.bonds);
  CHECK(a.dt == b.dt);
  CHECK(a.scheme == b.scheme);
  CHECK(a.step == b.step);
  CHECK(a.time == b.time);
  CHECK(a.u == b.u);
  CHECK(a.v == b.v);
  CHECK(a.f == b.f);
  CHECK(a.bond_state == b.bond_state);
  CHECK(a.external_work == b.external_work);
  CHECK(a.broken == b.broken);
}

std::string error_of(const fs::path& file) {
  try {
    read_checkpoint(file);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("a checkpoint reads back bit for bit") {
  const auto file = temp("roundtrip.h5");
  const auto c = sample(1000, 7000, 1.0);
  write_checkpoint(file, c);
  require_equal(read_checkpoint(file), c);
  CHECK_FALSE(fs::exists(file.string() + ".tmp"));
  // An empty body is still a valid file.
  write_checkpoint(file, sample(0, 0, 1.0));
  CHECK(read_checkpoint(file).points == 0);
  fs::remove(file);
}

TEST_CASE("a leftover tmp file never corrupts the last checkpoint") {
  const auto file = temp("atomic.h5");
  const auto tmp = fs::path(file.string() + ".tmp");
  const auto a = sample(500, 3000, 1.0);
  write_checkpoint(file, a);
  // A run killed while writing its next checkpoint leaves a partial .tmp behind.
  std::ofstream(tmp) << "partial garbage, not HDF5";
  require_equal(read_checkpoint(file), a);
  // The next write replaces the .tmp and then the checkpoint.
  const auto b = sample(500, 3000, 2.0);
  write_checkpoint(file, b);
  require_equal(read_checkpoint(file), b);
  CHECK_FALSE(fs::exists(tmp));
  fs::remove(file);
}

TEST_CASE("a writer killed at any moment leaves a whole checkpoint") {
  const auto file = temp("killed.h5");
  write_checkpoint(file, sample(100, 100, 1.0));
  // A child rewrites a 14 MB checkpoint in a loop, each with its own seed, and is killed
  // with SIGKILL at different moments; the file must always read back as one whole write.
  for (int delay_ms : {5, 23, 61, 97}) {
    const pid_t child = fork();
    REQUIRE(child >= 0);
    if (child == 0) {
      try {
        for (int k = 2;; ++k) write_checkpoint(file, sample(200000, 10, double(k)));
      } catch (...) {
      }
      _exit(1);  // never back into Catch
    }
    usleep(useconds_t(delay_ms * 1000));
    kill(child, SIGKILL);
    int status = 0;
    waitpid(child, &status, 0);
    CHECK(WIFSIGNALED(status));
    const auto c = read_checkpoint(file);
    REQUIRE((c.points == 100 || c.points == 200000));
    const double seed = c.external_work / 0.1;
    require_equal(c, sample(std::size_t(c.points), std::size_t(c.bonds), seed));
  }
  fs::remove(file);
  fs::remove(file.string() + ".tmp");
}

TEST_CASE("missing, truncated and foreign checkpoints are clear errors") {
  const auto file = temp("broken.h5");
  CHECK(error_of(temp("none.h5")).find("cannot open checkpoint file") != std::string::npos);
  std::ofstream(file) << "not an HDF5 file";
  CHECK(error_of(file).find("not an HDF5 file") != std::string::npos);
  // A checkpoint cut in half.
  write_checkpoint(file, sample(20000, 1000, 1.0));
  fs::resize_file(file, fs::file_size(file) / 2);
  const auto cut = error_of(file);
  INFO(cut);
  CHECK(cut.find("not a readable Peridot checkpoint") != std::string::npos);
  CHECK(cut.find(file.string()) != std::string::npos);
  fs::remove(file);
}

TEST_CASE("the deck hash ignores layout, name, output and end time") {
  const std::string deck = R"(name: a
dimension: 2
geometry: {body: {rectangle: {min: [0, 0], max: [0.01, 0.004]}}}
discretization: {spacing: 1.0e-3, horizon_factor: 3}
material: {model: pmb, youngs_modulus: 72.0e9, density: 2440.0, fracture_energy: 3.8}
solver: {type: explicit, end_time: 1.0e-6}
)";
  const auto h = parse_deck(deck).content_hash;
  // Key order, comments, flow vs block style, the name, output and solver.end_time: same hash.
  const std::string same = R"(# a comment
name: b
solver:
  end_time: 5.0e-6
  type: explicit
dimension: 2
material: {density: 2440.0, model: pmb, youngs_modulus: 72.0e9, fracture_energy: 3.8}
discretization: {horizon_factor: 3, spacing: 1.0e-3}
geometry: {body: {rectangle: {min: [0, 0], max: [0.01, 0.004]}}}
output: {csv: {every: 10}, checkpoint: {every: 5}}
)";
  CHECK(parse_deck(same).content_hash == h);
  // Any physical value: another hash.
  auto other = deck;
  other.replace(other.find("2440.0"), 6, "2441.0");
  CHECK(parse_deck(other).content_hash != h);
  other = deck;
  other.replace(other.find("horizon_factor: 3"), 17, "horizon_factor: 4");
  CHECK(parse_deck(other).content_hash != h);
}

TEST_CASE("output.checkpoint is checked and only explicit runs take it") {
  const std::string deck = R"(name: a
geometry: {body: {rectangle: {min: [0, 0], max: [0.01, 0.004]}}}
discretization: {spacing: 1.0e-3, horizon_factor: 3}
material: {model: pmb, youngs_modulus: 72.0e9, density: 2440.0, fracture_energy: 3.8}
solver: {type: explicit, end_time: 1.0e-6}
)";
  const auto p = parse_deck(deck);
  CHECK(p.output.checkpoint_every == 0);
  CHECK(p.output.checkpoint_file == "a.h5");
  const auto q = parse_deck(deck + "output: {checkpoint: {every: 7, file: run.h5}}\n");
  CHECK(q.output.checkpoint_every == 7);
  CHECK(q.output.checkpoint_file == "run.h5");
  const auto message = [&](const std::string& extra) {
    try {
      parse_deck(deck + extra);
    } catch (const DeckError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  CHECK(message("output: {checkpoint: {every: -1}}\n").find("output.checkpoint.every") != std::string::npos);
  CHECK(message("output: {checkpoint: {file: ../x.h5}}\n").find("output.checkpoint.file = '../x.h5'") != std::string::npos);
  CHECK(message("output: {checkpoint: {file: run.hdf}}\n").find("must end in '.h5'") != std::string::npos);
  CHECK(message("output: {checkpoint: {evry: 3}}\n").find("unknown key 'evry'") != std::string::npos);
}
