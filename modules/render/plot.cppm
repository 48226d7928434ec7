export module peridot.render:plot;
import peridot.std;

export namespace peridot {

// One curve of a plot: y against the plot's shared abscissa.
struct PlotLine {
  std::string name;
  std::vector<double> y;
};

// A panel: curves sharing a y axis.
struct PlotPanel {
  std::string y_label;
  std::vector<PlotLine> lines;
};

struct PlotOptions {
  std::string title;
  std::string x_label = "time [s]";
  int width = 1200;         // [px]
  int panel_height = 260;   // [px] per panel
};

// Line plots of several panels over one abscissa, stacked, written as a PNG atomically.
// Non-finite values are left out of the curves. Throws std::invalid_argument when a line's
// length differs from x's, std::runtime_error when the file cannot be written.
void plot_png(const std::filesystem::path& file, std::span<const double> x, std::span<const PlotPanel> panels, const PlotOptions& options = {});

}  // namespace peridot
