#pragma once
// Typed access to one TOML table of a scene file. Every failure is a
// SceneError of one line: "<file>: field '<path>': expected <what>, got <what>".
// finish() rejects keys nobody asked for, so typos do not pass silently.

#include "phasecast/precompute/simulation/scene.h"

#include <toml++/toml.h>

#include <Eigen/Core>

#include <optional>
#include <set>
#include <string>
#include <vector>

namespace phasecast::precompute::detail {

class Fields {
 public:
  Fields(const toml::table& table, std::string file, std::string prefix);

  bool has(const std::string& key) const;
  bool is_string(const std::string& key) const;  // present and a string
  std::string path(const std::string& key) const { return prefix_ + key; }
  [[noreturn]] void fail(const std::string& key, const std::string& expected) const;

  std::string string(const std::string& key);
  std::optional<std::string> optional_string(const std::string& key);
  bool flag(const std::string& key, bool fallback);  // true or false
  double number(const std::string& key);
  double number(const std::string& key, double fallback);
  double positive(const std::string& key);
  double positive(const std::string& key, double fallback);
  int positive_integer(const std::string& key, int fallback);
  Eigen::Vector3d vec3(const std::string& key);
  Eigen::Vector3d vec3(const std::string& key, const Eigen::Vector3d& fallback);
  Eigen::Vector3d albedo(const std::string& key, const Eigen::Vector3d& fallback);  // [r, g, b] in [0, 1]
  std::vector<double> numbers(const std::string& key, size_t count);
  std::vector<std::string> strings(const std::string& key);
  std::vector<Eigen::Vector3d> points(const std::string& key);
  Fields table(const std::string& key);
  std::vector<Fields> tables(const std::string& key);  // array of tables; empty when absent

  void mark_used(const std::string& key) { used_.insert(key), known_.insert(key); }
  void finish() const;
  const std::string& file() const { return file_; }
  const std::string& prefix() const { return prefix_; }

 private:
  const toml::node* node(const std::string& key);
  std::string got(const std::string& key) const;
  const toml::table* table_;
  std::string file_;
  std::string prefix_;
  std::set<std::string> used_;
  // Every key asked for, present or not: what a misspelt key is compared with.
  mutable std::set<std::string> known_;
};

}  // namespace phasecast::precompute::detail
