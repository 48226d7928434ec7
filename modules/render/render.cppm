// peridot.render: headless PNG snapshots of a nodal field (damage by default) over a 2D
// body, or a slice or projection of a 3D one. The interface needs no OpenCV header.
export module peridot.render;
import peridot.std;
export import :options;
export import :layout;
export import :spacing;
export import :plot;
export import :saved_field;

export namespace peridot {

// Draws the field and writes a PNG atomically (via `file.tmp`). Throws
// std::invalid_argument for bad fields or options and std::runtime_error when the file
// cannot be written.
void render_png(const std::filesystem::path& file, const RenderField& field, const RenderOptions& options = {});

// The same image as encoded PNG bytes (for sending or embedding).
std::vector<unsigned char> render_png_bytes(const RenderField& field, const RenderOptions& options = {});

// A field held in parts (RenderParts): collective over the parts. The root part writes the
// file or gets the bytes; the others get nothing. Bad input throws on every part.
void render_png(const std::filesystem::path& file, const RenderField& part, const RenderOptions& options, const RenderParts& parts);
std::vector<unsigned char> render_png_bytes(const RenderField& part, const RenderOptions& options, const RenderParts& parts);

}  // namespace peridot
