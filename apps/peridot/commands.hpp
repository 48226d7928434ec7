#pragma once
#include <optional>
#include <string>
#include <vector>

// Exit codes of the peridot CLI (documented in README.md).
enum ExitCode : int {
  exit_ok = 0,
  exit_runtime_error = 1,  // the run started but failed (diverged, I/O error)
  exit_input_error = 2,    // bad deck, missing file, invalid option
};

struct RunArgs {
  std::optional<std::string> deck;     // none: the embedded default deck
  std::optional<std::string> out_dir;  // overrides output.directory
  int threads = 0;                     // 0: OpenMP default
  std::optional<std::string> run_id;   // DDS run id (default <name>-<pid>)
  int dds_domain = 0;                  // DDS domain id
  std::string dds_partition;           // DDS partition (empty: the default one)
  bool quiet = false;
  std::optional<std::string> restart;  // HDF5 checkpoint to continue from (explicit runs)
  std::size_t max_steps = 0;           // end after this many steps, load increments or solves (0: the deck's end)
};

struct ConvergeArgs {
  std::string deck;
  std::vector<int> cells{16, 32, 64};  // cells across the body's x extent
  int clouds = 1;                      // perturbed decks: RMS over this many random clouds
  std::optional<std::string> out_dir;
};

struct RenderArgs {
  std::string input;            // .pvd or .vtu
  std::string field = "damage";
  int width = 1200;
  bool deformed = false;
  double magnification = 1.0;
  bool last_only = false;
};

struct MeshArgs {
  std::string geo;                 // the .geo file to mesh
  double size = 0;                 // element size [m] (0: the sizes in the file)
  int dimension = 2;               // 2: triangles, 3: tetrahedra
  std::optional<std::string> out;  // the .msh to write (default: <stem>.msh here)
};

int run_command(const RunArgs& args);
int mesh_command(const MeshArgs& args);
int render_command(const RenderArgs& args);
int converge_command(const ConvergeArgs& args);
int check_command(const std::string& deck);
