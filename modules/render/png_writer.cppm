module;
#include <dlfcn.h>
#include <errno.h>
#include <unistd.h>
#include <opencv2/core.hpp>
module peridot.render:png_writer;
import peridot.std;

namespace peridot {

namespace {

using EncodePng = int (*)(const cv::Mat*, int, std::vector<unsigned char>*, char*, std::size_t);

// The encoder plugin (png_codec.cpp), opened on the first image: next to the executable, else
// where the build put it (PERIDOT_PNG_CODEC).
EncodePng png_encoder() {
  static const EncodePng encode = [] {
    std::vector<std::string> tried;
    std::error_code ec;
    char self[4096];
    const auto n = readlink("/proc/self/exe", self, sizeof self - 1);
    const std::filesystem::path built = PERIDOT_PNG_CODEC;
    const auto beside = n > 0 ? std::filesystem::path(std::string(self, std::size_t(n))).parent_path() / built.filename() : std::filesystem::path();
    for (const auto& candidate : {beside, built}) {
      if (candidate.empty() || !std::filesystem::exists(candidate, ec)) continue;
      if (void* lib = dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL)) {
        if (auto f = reinterpret_cast<EncodePng>(dlsym(lib, "peridot_encode_png"))) return f;
        tried.push_back(candidate.string() + ": no peridot_encode_png");
      } else {
        tried.push_back(dlerror());
      }
    }
    if (tried.empty()) tried.push_back(fmt::format("{} not found, nor next to the executable", built.string()));
    std::string why;
    for (const auto& t : tried) why += (why.empty() ? "" : "; ") + t;
    throw std::runtime_error("render: cannot load the PNG encoder: " + why);
  }();
  return encode;
}

}  // namespace

// Encodes a BGR image as PNG in memory.
std::vector<unsigned char> encode_png(const cv::Mat& image) {
  std::vector<unsigned char> bytes;
  char error[512] = "";
  // Level 6 of 9: most of the size gain for a fraction of the time of 9.
  if (!png_encoder()(&image, 6, &bytes, error, sizeof error)) throw std::runtime_error(std::string("render: ") + error);
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
