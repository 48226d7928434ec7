// The PNG encoder, a plugin that peridot.render opens on the first image it writes (see
// png_writer.cppm). It is the one piece of Peridot that needs OpenCV's imgcodecs, which on
// Debian brings GDAL and about 140 shared libraries: linked into every binary they cost each
// process 0.1 s at start-up, images or not.
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <exception>
#include <vector>

// Returns 1 on success; on failure 0, with the reason in `error` (NUL-terminated).
extern "C" __attribute__((visibility("default"))) int peridot_encode_png(const cv::Mat* image, int level, std::vector<unsigned char>* bytes,
                                                                         char* error, std::size_t error_size) noexcept {
  try {
    if (cv::imencode(".png", *image, *bytes, {cv::IMWRITE_PNG_COMPRESSION, level})) return 1;
    std::snprintf(error, error_size, "OpenCV could not encode the image as PNG");
  } catch (const std::exception& e) {
    std::snprintf(error, error_size, "OpenCV could not encode the image as PNG: %s", e.what());
  }
  return 0;
}
