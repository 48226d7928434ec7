module;
#include <yaml-cpp/yaml.h>
export module peridot.io:deck_reader;
import peridot.std;

export namespace peridot {

// Any problem with a deck: the message names the field, the value and what is allowed.
struct DeckError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Errors that mean bad input (exit 2): a DeckError, or a std::invalid_argument from a lower layer.
inline bool is_input_error(const std::exception& e) {
  return dynamic_cast<const DeckError*>(&e) != nullptr || dynamic_cast<const std::invalid_argument*>(&e) != nullptr;
}

// Allowed interval for a number; open or closed at each end.
struct Range {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false, hi_open = false;
  static Range positive() { return {0, std::numeric_limits<double>::infinity(), true, false}; }
  static Range non_negative() { return {0, std::numeric_limits<double>::infinity(), false, false}; }
  static Range between(double a, double b) { return {a, b, false, false}; }
  bool contains(double v) const {
    return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  }
  std::string describe() const;
};

// A YAML map being read: tracks the dotted path for messages and which keys were used,
// so that unknown keys are reported instead of silently ignored.
class DeckMap {
 public:
  DeckMap(YAML::Node node, std::string path);
  const std::string& path() const { return path_; }
  bool has(const std::string& key) const;
  YAML::Node raw(const std::string& key);

  double number(const std::string& key, Range r);
  double number(const std::string& key, Range r, double fallback);
  long integer(const std::string& key, Range r, long fallback);
  bool flag(const std::string& key, bool fallback);
  std::string text(const std::string& key);
  std::string text(const std::string& key, const std::string& fallback);
  std::string choice(const std::string& key, const std::vector<std::string>& allowed, const std::string& fallback = "");
  std::vector<double> numbers(const std::string& key, std::size_t min_len, std::size_t max_len, Range r = {});
  DeckMap map(const std::string& key);
  std::optional<DeckMap> optional_map(const std::string& key);
  std::vector<YAML::Node> list(const std::string& key);  // empty if absent
  std::string child_path(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

  // Throws for any key that was never read.
  void finish() const;

  [[noreturn]] void fail(const std::string& key, const std::string& what) const;

 private:
  void report_stray(const std::string& missing) const;
  YAML::Node node_;
  std::string path_;
  mutable std::set<std::string> used_, known_;
};

double parse_number(const YAML::Node& n, const std::string& path, Range r);

// A value as shown in a message: at most 60 characters, so a huge value is not echoed.
std::string shown(const std::string& value);

// Every key path a DeckMap asks about while it is installed (list indices as []), for the
// test that keeps the documented schema and the parser's keys equal. Not thread-safe; off
// (null) unless a test installs one.
struct DeckKeyLog {
  std::set<std::string> keys;
};
void set_deck_key_log(DeckKeyLog* log);

}  // namespace peridot

namespace peridot {

namespace {

std::string fmt_num(double v) { return fmt::format("{:g}", v); }

DeckKeyLog* key_log = nullptr;

std::string without_indices(const std::string& path) {
  std::string out;
  for (std::size_t k = 0; k < path.size(); ++k) {
    if (path[k] != '[') {
      out += path[k];
      continue;
    }
    out += "[]";
    while (k < path.size() && path[k] != ']') ++k;
  }
  return out;
}

// Levenshtein distance, for "did you mean" on unknown keys.
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

}  // namespace

void set_deck_key_log(DeckKeyLog* log) { key_log = log; }

std::string shown(const std::string& value) {
  constexpr std::size_t limit = 60;
  if (value.size() <= limit) return value;
  return fmt::format("{}... ({} characters)", value.substr(0, limit), value.size());
}

std::string Range::describe() const {
  const bool has_lo = std::isfinite(lo), has_hi = std::isfinite(hi);
  if (has_lo && has_hi) return fmt::format("{}{}, {}{}", lo_open ? "(" : "[", fmt_num(lo), fmt_num(hi), hi_open ? ")" : "]");
  if (has_lo) return fmt::format("{} {}", lo_open ? ">" : ">=", fmt_num(lo));
  if (has_hi) return fmt::format("{} {}", hi_open ? "<" : "<=", fmt_num(hi));
  return "any finite number";
}

double parse_number(const YAML::Node& n, const std::string& path, Range r) {
  if (!n.IsScalar()) throw DeckError(fmt::format("{}: expected a number, allowed range {}", path, r.describe()));
  double v = 0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    throw DeckError(fmt::format("{} = '{}': not a number, allowed range {}", path, shown(n.Scalar()), r.describe()));
  }
  if (!std::isfinite(v)) throw DeckError(fmt::format("{} = {}: must be a finite number in {}", path, shown(n.Scalar()), r.describe()));
  if (!r.contains(v)) throw DeckError(fmt::format("{} = {}: out of range, allowed {}", path, shown(n.Scalar()), r.describe()));
  return v;
}

DeckMap::DeckMap(YAML::Node node, std::string path) : node_(std::move(node)), path_(std::move(path)) {
  if (node_.IsNull()) node_ = YAML::Node(YAML::NodeType::Map);  // an empty section reports its missing keys
  if (!node_.IsMap()) throw DeckError(fmt::format("{}: expected a mapping of keys to values", path_.empty() ? "deck" : path_));
  // YAML forbids duplicate keys but yaml-cpp keeps both and reads the first: refuse them.
  std::set<std::string> seen;
  for (const auto& kv : node_) {
    if (!kv.first.IsScalar()) throw DeckError(fmt::format("{}: keys must be plain names", path_.empty() ? "deck" : path_));
    const auto k = kv.first.Scalar();
    if (!seen.insert(k).second)
      throw DeckError(fmt::format("{}: key '{}' appears more than once (line {})", child_path(shown(k)), shown(k), kv.first.Mark().line + 1));
  }
}

bool DeckMap::has(const std::string& key) const {
  known_.insert(key);
  if (key_log) key_log->keys.insert(without_indices(child_path(key)));
  return bool(node_[key]);
}

YAML::Node DeckMap::raw(const std::string& key) {
  used_.insert(key);
  return node_[key];
}

void DeckMap::fail(const std::string& key, const std::string& what) const {
  // A missing key is often a misspelt one: name the stray key first.
  if (!node_[key]) report_stray(key);
  // "field = value: reason" reads better than "field: = value: reason".
  throw DeckError(fmt::format("{}{}{}", child_path(key), what.starts_with("= ") ? " " : ": ", what));
}

double DeckMap::number(const std::string& key, Range r) {
  if (!has(key)) fail(key, fmt::format("required number is missing, allowed range {}", r.describe()));
  return parse_number(raw(key), child_path(key), r);
}

double DeckMap::number(const std::string& key, Range r, double fallback) {
  return has(key) ? number(key, r) : fallback;
}

long DeckMap::integer(const std::string& key, Range r, long fallback) {
  if (!has(key)) return fallback;
  const double v = number(key, r);
  if (v != std::floor(v)) fail(key, fmt::format("= {}: must be an integer in {}", fmt_num(v), r.describe()));
  return long(v);
}

bool DeckMap::flag(const std::string& key, bool fallback) {
  if (!has(key)) return fallback;
  try {
    return raw(key).as<bool>();
  } catch (const YAML::Exception&) {
    fail(key, "expected true or false");
  }
}

std::string DeckMap::text(const std::string& key) {
  if (!has(key)) fail(key, "required text is missing");
  const auto n = raw(key);
  if (!n.IsScalar()) fail(key, "expected text");
  return n.Scalar();
}

std::string DeckMap::text(const std::string& key, const std::string& fallback) { return has(key) ? text(key) : fallback; }

std::string DeckMap::choice(const std::string& key, const std::vector<std::string>& allowed, const std::string& fallback) {
  std::string all;
  for (const auto& a : allowed) all += (all.empty() ? "" : ", ") + a;
  if (!has(key)) {
    if (fallback.empty()) fail(key, fmt::format("required, one of: {}", all));
    return fallback;
  }
  const auto v = text(key);
  for (const auto& a : allowed)
    if (a == v) return v;
  fail(key, fmt::format("= '{}': must be one of: {}", shown(v), all));
}

std::vector<double> DeckMap::numbers(const std::string& key, std::size_t min_len, std::size_t max_len, Range r) {
  if (!has(key)) fail(key, fmt::format("required list of {} to {} numbers is missing", min_len, max_len));
  const auto n = raw(key);
  if (!n.IsSequence() || n.size() < min_len || n.size() > max_len)
    fail(key, fmt::format("expected a list of {} to {} numbers", min_len, max_len));
  std::vector<double> out;
  for (std::size_t k = 0; k < n.size(); ++k) out.push_back(parse_number(n[k], fmt::format("{}[{}]", child_path(key), k), r));
  return out;
}

DeckMap DeckMap::map(const std::string& key) {
  if (!has(key)) fail(key, "required section is missing");
  return DeckMap(raw(key), child_path(key));
}

std::optional<DeckMap> DeckMap::optional_map(const std::string& key) {
  if (!has(key)) return std::nullopt;
  return DeckMap(raw(key), child_path(key));
}

std::vector<YAML::Node> DeckMap::list(const std::string& key) {
  if (!has(key)) return {};
  const auto n = raw(key);
  if (!n.IsSequence()) fail(key, "expected a list");
  return {n.begin(), n.end()};
}

void DeckMap::report_stray(const std::string& missing) const {
  for (const auto& kv : node_) {
    const auto k = kv.first.Scalar();
    if (known_.count(k) || used_.count(k)) continue;
    if (edit_distance(k, missing) <= std::max<std::size_t>(2, missing.size() / 4))
      throw DeckError(fmt::format("{}: unknown key '{}' (did you mean '{}'?)", path_.empty() ? "deck" : path_, shown(k), missing));
  }
}

void DeckMap::finish() const {
  for (const auto& kv : node_) {
    const auto k = kv.first.Scalar();
    if (used_.count(k)) continue;
    std::string allowed, closest;
    std::size_t best = 3;
    for (const auto& a : known_) {
      allowed += (allowed.empty() ? "" : ", ") + a;
      if (const auto d = edit_distance(k, a); d < best) best = d, closest = a;
    }
    throw DeckError(fmt::format("{}: unknown key '{}'{} (allowed here: {})", path_.empty() ? "deck" : path_, shown(k),
                                closest.empty() ? "" : fmt::format(", did you mean '{}'?", closest), allowed));
  }
}

}  // namespace peridot
