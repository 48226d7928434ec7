module;
#include <opencv2/core.hpp>
module peridot.render;
import peridot.std;
import :canvas;
import :png_writer;

namespace peridot {

std::vector<unsigned char> render_png_bytes(const RenderField& field, const RenderOptions& options) {
  const Scene scene = build_scene(field, options);
  return encode_png(paint(scene, field, options));
}

void render_png(const std::filesystem::path& file, const RenderField& field, const RenderOptions& options) {
  write_atomically(file, render_png_bytes(field, options));
}

}  // namespace peridot
