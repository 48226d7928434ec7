module;
#include <errno.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
module peridot.render:png_writer;
import peridot.std;

namespace peridot {

// Encodes a BGR image as PNG in memory.
std::vector<unsigned char> encode_png(const cv::Mat& image) {
  std::vector<unsigned char> bytes;
  // Level 6 of 9: most of the size gain for a fraction of the time of 9.
  if (!cv::imencode(".png", image, bytes, {cv::IMWRITE_PNG_COMPRESSION, 6}))
    throw std::runtime_error("render: OpenCV could not encode the image as PNG");
  return bytes;
}

// Writes `bytes` to `file.tmp` and renames it over `file`, so readers (a viewer polling the
// file) never see a half-written image.
void write_atomically(const std::filesystem::path& file, const std::vector<unsigned char>& bytes) {
  if (file.empty()) throw std::invalid_argument("render: the output path is empty");
  std::filesystem::path tmp = file;
  tmp += ".tmp";
  auto fail = [&](const std::string& why) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw std::runtime_error("render: cannot write '" + file.string() + "': " + why);
  };
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) {
      const auto dir = file.parent_path();
      std::error_code ec;
      if (!dir.empty() && !std::filesystem::is_directory(dir, ec)) fail("directory '" + dir.string() + "' does not exist");
      fail(std::strerror(errno));
    }
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    out.flush();
    if (!out) fail("writing '" + tmp.string() + "' failed (disk full?)");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) fail("renaming '" + tmp.string() + "' failed: " + ec.message());
}

}  // namespace peridot
