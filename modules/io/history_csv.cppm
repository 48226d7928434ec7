module;
#include <peridot/run_record.hpp>
export module peridot.io:history_csv;
import peridot.std;
import :files;

export namespace peridot {


// CSV history, one row per output step, written per row so a crash keeps whole rows only; a
// row that cannot be written in full (a full disk) is cut off and throws naming the file.
// Columns follow for_each_field: name_unit (e.g. time_s, tip_speed_m_s).
class HistoryCsv {
 public:
  // keep_before_step > 0 continues a restarted run's history: whole rows of an existing file
  // with step < keep_before_step are kept (rewritten atomically), later ones dropped; a file
  // with another header is started afresh.
  explicit HistoryCsv(const std::filesystem::path& file, std::size_t keep_before_step = 0);
  void append(const RunRecord& r);
  static std::string header();

 private:
  std::unique_ptr<RecordFile> file_;
};

}  // namespace peridot

namespace peridot {

std::string HistoryCsv::header() {
  std::string h;
  const RunRecord r{};
  for_each_field(r, [&](const char* name, std::string unit, const auto&) {
    for (auto& c : unit) c = c == '/' ? '_' : c;
    h += fmt::format("{}{}{}{}", h.empty() ? "" : ",", name, unit.empty() ? "" : "_", unit);
  });
  return h;
}

namespace {

// The rows of an existing history before step `before`; a partial row (a run killed while
// writing it) ends them.
std::string rows_before(const std::filesystem::path& file, const std::string& header, std::size_t before) {
  std::ifstream in(file);
  std::string line, rows;
  if (!in || !std::getline(in, line) || line != header) return rows;
  const auto columns = std::count(header.begin(), header.end(), ',');
  while (std::getline(in, line) && !in.eof() && std::count(line.begin(), line.end(), ',') == columns) {
    std::size_t step = 0;
    const auto [end, ec] = std::from_chars(line.data(), line.data() + line.size(), step);
    if (ec != std::errc() || *end != ',' || step >= before) break;
    rows += line + '\n';
  }
  return rows;
}

}  // namespace

HistoryCsv::HistoryCsv(const std::filesystem::path& file, std::size_t keep_before_step) {
  if (keep_before_step > 0) {
    write_file_atomically(file, {header(), "\n", rows_before(file, header(), keep_before_step)});
    file_ = std::make_unique<RecordFile>(file, true);
  } else {
    file_ = std::make_unique<RecordFile>(file);
    file_->append(header() + '\n');
  }
}

void HistoryCsv::append(const RunRecord& r) {
  std::string row;
  for_each_field(r, [&](const char*, const char*, const auto& v) {
    if (!row.empty()) row += ',';
    if constexpr (std::is_floating_point_v<std::remove_cvref_t<decltype(v)>>) row += fmt::format("{:.9e}", v);
    else row += fmt::format("{}", v);
  });
  row += '\n';
  file_->append(row);
}

}  // namespace peridot
