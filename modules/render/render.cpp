module;
#include <opencv2/core.hpp>
module peridot.render;
import peridot.std;
import :canvas;
import :png_writer;

namespace peridot {

std::vector<unsigned char> render_png_bytes(const RenderField& part, const RenderOptions& options, const RenderParts& parts) {
  const Scene scene = build_scene(part, options, parts);
  if (!parts.root) return {};
  return encode_png(paint(scene, part, options));
}

std::vector<unsigned char> render_png_bytes(const RenderField& field, const RenderOptions& options) {
  return render_png_bytes(field, options, RenderParts{});
}

void render_png(const std::filesystem::path& file, const RenderField& part, const RenderOptions& options, const RenderParts& parts) {
  const auto bytes = render_png_bytes(part, options, parts);
  if (parts.root) write_atomically(file, bytes);
}

void render_png(const std::filesystem::path& file, const RenderField& field, const RenderOptions& options) {
  render_png(file, field, options, RenderParts{});
}

}  // namespace peridot
