#include "phasecast/precompute/simulation/scene_fields.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

namespace phasecast::precompute::detail {
namespace {

std::string describe(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::string:
      return fmt::format("string \"{}\"", n.as_string()->get());
    case toml::node_type::integer:
      return fmt::format("integer {}", n.as_integer()->get());
    case toml::node_type::floating_point:
      return fmt::format("number {}", n.as_floating_point()->get());
    case toml::node_type::boolean:
      return fmt::format("boolean {}", n.as_boolean()->get());
    case toml::node_type::array:
      return fmt::format("array of {}", n.as_array()->size());
    case toml::node_type::table:
      return "table";
    default:
      return "a date/time";
  }
}

std::optional<double> as_number(const toml::node& n) {
  if (const auto* i = n.as_integer()) return static_cast<double>(i->get());
  if (const auto* f = n.as_floating_point()) return f->get();
  return std::nullopt;
}

// Levenshtein distance: how many single-character edits make `a` into `b`.
size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

// A misspelling is at most two edits away (and shorter keys need closer ones).
bool close_enough(const std::string& a, const std::string& b) {
  const size_t d = edit_distance(a, b);
  return d > 0 && d <= std::min<size_t>(2, std::max(a.size(), b.size()) / 3);
}

// A key a user likely wrote for another: a typo of it, or it with more
// words (`young_modulus` for `young`, `dt` for `frame_dt`).
bool likely_meant(const std::string& written, const std::string& known) {
  const bool contains =
      std::min(written.size(), known.size()) >= 2 && written != known &&
      (written.find(known) != std::string::npos || known.find(written) != std::string::npos);
  return close_enough(written, known) || contains;
}

}  // namespace

Fields::Fields(const toml::table& table, std::string file, std::string prefix)
    : table_(&table), file_(std::move(file)), prefix_(std::move(prefix)) {}

bool Fields::has(const std::string& key) const {
  known_.insert(key);
  return table_->contains(key);
}

bool Fields::is_string(const std::string& key) const {
  const toml::node* n = table_->get(key);
  return n && n->is_string();
}

std::string Fields::got(const std::string& key) const {
  if (const toml::node* n = table_->get(key)) return describe(*n);
  // A key of the file nobody asked for, likely written for this one: the cause.
  for (const auto& [other, value] : *table_) {
    const std::string name(other.str());
    if (!known_.count(name) && likely_meant(name, key))
      return fmt::format("nothing (missing; the file has '{}', misspelt?)", path(name));
  }
  return "nothing (missing)";
}

void Fields::fail(const std::string& key, const std::string& expected) const {
  throw SceneError(fmt::format("{}: field '{}': expected {}, got {}", file_, path(key), expected, got(key)));
}

const toml::node* Fields::node(const std::string& key) {
  used_.insert(key);
  known_.insert(key);
  return table_->get(key);
}

std::string Fields::string(const std::string& key) {
  const toml::node* n = node(key);
  if (!n || !n->is_string()) fail(key, "a string");
  return n->as_string()->get();
}

std::optional<std::string> Fields::optional_string(const std::string& key) {
  if (!has(key)) return std::nullopt;
  return string(key);
}

bool Fields::flag(const std::string& key, bool fallback) {
  if (!has(key)) return fallback;
  const toml::node* n = node(key);
  if (!n->is_boolean()) fail(key, "true or false");
  return n->as_boolean()->get();
}

double Fields::number(const std::string& key) {
  const toml::node* n = node(key);
  const auto v = n ? as_number(*n) : std::nullopt;
  if (!v || !std::isfinite(*v)) fail(key, "a finite number");
  return *v;
}

double Fields::number(const std::string& key, double fallback) {
  return has(key) ? number(key) : fallback;
}

double Fields::positive(const std::string& key) {
  const toml::node* n = node(key);
  const auto v = n ? as_number(*n) : std::nullopt;
  if (!v || !(*v > 0) || !std::isfinite(*v)) fail(key, "a positive number");
  return *v;
}

double Fields::positive(const std::string& key, double fallback) {
  return has(key) ? positive(key) : fallback;
}

int Fields::positive_integer(const std::string& key, int fallback) {
  if (!has(key)) return fallback;
  const toml::node* n = node(key);
  if (!n->is_integer() || n->as_integer()->get() < 1 || n->as_integer()->get() > 1'000'000) {
    fail(key, "a positive integer");
  }
  return static_cast<int>(n->as_integer()->get());
}

std::vector<double> Fields::numbers(const std::string& key, size_t count) {
  const toml::node* n = node(key);
  const std::string expected = fmt::format("an array of {} finite numbers", count);
  if (!n || !n->is_array() || n->as_array()->size() != count) fail(key, expected);
  std::vector<double> out;
  for (const auto& e : *n->as_array()) {
    const auto v = as_number(e);
    if (!v || !std::isfinite(*v)) fail(key, expected);
    out.push_back(*v);
  }
  return out;
}

Eigen::Vector3d Fields::vec3(const std::string& key) {
  const auto v = numbers(key, 3);
  return {v[0], v[1], v[2]};
}

Eigen::Vector3d Fields::vec3(const std::string& key, const Eigen::Vector3d& fallback) {
  return has(key) ? vec3(key) : fallback;
}

Eigen::Vector3d Fields::albedo(const std::string& key, const Eigen::Vector3d& fallback) {
  if (!has(key)) return fallback;
  const std::string expected = "[r, g, b] with each in [0, 1]";
  const toml::node* n = node(key);
  if (!n->is_array() || n->as_array()->size() != 3) fail(key, expected);
  Eigen::Vector3d rgb;
  for (int c = 0; c < 3; ++c) {
    const auto v = as_number(*n->as_array()->get(static_cast<size_t>(c)));
    if (!v || !(*v >= 0 && *v <= 1)) fail(key, expected);
    rgb[c] = *v;
  }
  return rgb;
}

std::vector<std::string> Fields::strings(const std::string& key) {
  const toml::node* n = node(key);
  if (!n || !n->is_array()) fail(key, "an array of strings");
  std::vector<std::string> out;
  for (const auto& e : *n->as_array()) {
    if (!e.is_string()) fail(key, "an array of strings");
    out.push_back(e.as_string()->get());
  }
  return out;
}

std::vector<Eigen::Vector3d> Fields::points(const std::string& key) {
  const toml::node* n = node(key);
  const char* expected = "an array of [x, y, z] points";
  if (!n || !n->is_array()) fail(key, expected);
  std::vector<Eigen::Vector3d> out;
  for (const auto& e : *n->as_array()) {
    const auto* p = e.as_array();
    if (!p || p->size() != 3) fail(key, expected);
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) {
      const auto c = as_number(*p->get(static_cast<size_t>(k)));
      if (!c || !std::isfinite(*c)) fail(key, expected);
      v[k] = *c;
    }
    out.push_back(v);
  }
  return out;
}

Fields Fields::table(const std::string& key) {
  const toml::node* n = node(key);
  if (!n || !n->is_table()) fail(key, "a table");
  return Fields(*n->as_table(), file_, path(key) + ".");
}

std::vector<Fields> Fields::tables(const std::string& key) {
  std::vector<Fields> out;
  if (!has(key)) return out;
  const toml::node* n = node(key);
  if (!n->is_array_of_tables()) fail(key, fmt::format("an array of tables ([[{}]])", key));
  size_t i = 0;
  for (const auto& e : *n->as_array())
    out.emplace_back(*e.as_table(), file_, fmt::format("{}[{}].", path(key), i++));
  return out;
}

void Fields::finish() const {
  for (const auto& [key, value] : *table_) {
    const std::string name(key.str());
    if (used_.count(name)) continue;
    std::string nearest;
    for (const auto& k : known_)
      if (likely_meant(name, k) && (nearest.empty() || edit_distance(name, k) < edit_distance(name, nearest)))
        nearest = k;
    // Otherwise every key this table knows (known_ is ordered), so the right one is in the line.
    throw SceneError(fmt::format("{}: field '{}': unknown field ({})", file_, path(name),
                                 nearest.empty() ? fmt::format("expected one of {}", fmt::join(known_, ", "))
                                                 : fmt::format("did you mean '{}'?", path(nearest))));
  }
}

}  // namespace phasecast::precompute::detail
