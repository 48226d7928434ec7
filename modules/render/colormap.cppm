module;
#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
module peridot.render:colormap;

namespace peridot {

// Viridis: perceptually uniform, ordered in lightness and readable by colour-blind
// viewers and in greyscale print. The 256-entry table comes from OpenCV's own colormap.
class Colormap {
 public:
  Colormap(double vmin, double vmax) : vmin_(vmin), inv_range_(1.0 / (vmax - vmin)) {
    cv::Mat ramp(1, 256, CV_8UC1), bgr;
    for (int i = 0; i < 256; ++i) ramp.at<unsigned char>(0, i) = static_cast<unsigned char>(i);
    cv::applyColorMap(ramp, bgr, cv::COLORMAP_VIRIDIS);
    for (int i = 0; i < 256; ++i) table_[i] = bgr.at<cv::Vec3b>(0, i);
  }
  // Colour of a value; out-of-range values saturate, NaN is a neutral grey no viridis entry has.
  cv::Vec3b operator()(double v) const {
    if (std::isnan(v)) return nan_colour;
    return at(std::clamp((v - vmin_) * inv_range_, 0.0, 1.0));
  }
  // Colour at a fraction t in [0, 1] of the range.
  cv::Vec3b at(double t) const { return table_[static_cast<int>(std::lround(t * 255.0))]; }

  static inline const cv::Vec3b nan_colour{150, 150, 150};

 private:
  double vmin_, inv_range_;
  std::array<cv::Vec3b, 256> table_;
};

}  // namespace peridot
