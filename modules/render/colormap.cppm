module;
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
module peridot.render:colormap;
import peridot.std;
import :layout;

namespace peridot {

// Viridis: perceptually uniform, ordered in lightness and readable by colour-blind
// viewers and in greyscale print. The 256-entry table comes from OpenCV's own colormap.
class Colormap {
 public:
  Colormap() {
    cv::Mat ramp(1, colour_levels, CV_8UC1), bgr;
    for (int i = 0; i < colour_levels; ++i) ramp.at<unsigned char>(0, i) = static_cast<unsigned char>(i);
    cv::applyColorMap(ramp, bgr, cv::COLORMAP_VIRIDIS);
    for (int i = 0; i < colour_levels; ++i) table_[std::size_t(i)] = bgr.at<cv::Vec3b>(0, i);
  }
  // Colour of a colour_level; NaN is a neutral grey that no viridis entry has.
  cv::Vec3b level(int l) const { return l == nan_level ? nan_colour : table_[std::size_t(l)]; }
  // Colour at a fraction t in [0, 1] of the range.
  cv::Vec3b at(double t) const { return table_[std::size_t(std::lround(std::clamp(t, 0.0, 1.0) * (colour_levels - 1)))]; }

  static inline const cv::Vec3b nan_colour{150, 150, 150};

 private:
  std::array<cv::Vec3b, colour_levels> table_;
};

}  // namespace peridot
