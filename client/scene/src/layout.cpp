#include "phasecast/client/layout.h"

#include <fmt/format.h>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <numbers>
#include <stdexcept>

namespace phasecast::client {
namespace {

using nlohmann::json;

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what) {
  throw std::invalid_argument(fmt::format("--layout {}: {}", file.string(), what));
}

float finite_number(const json& v, const std::filesystem::path& file, const std::string& where) {
  if (!v.is_number() || !std::isfinite(v.get<double>())) fail(file, where + " is not a finite number");
  return v.get<float>();
}

Eigen::Matrix4f placement(const json& entry, const std::filesystem::path& file, std::size_t k) {
  const std::string at = fmt::format("placements[{}]", k);
  if (!entry.is_object())
    fail(file, at + " is not an object (expected {\"translate\": [x, y, z], \"rotate_y_deg\": a})");
  Eigen::Matrix4f m = Eigen::Matrix4f::Identity();
  for (const auto& [key, value] : entry.items()) {
    if (key == "translate") {
      if (!value.is_array() || value.size() != 3)
        fail(file, at + ".translate is not three numbers [x, y, z]");
      for (int i = 0; i < 3; ++i)
        m(i, 3) =
            finite_number(value[static_cast<std::size_t>(i)], file, fmt::format("{}.translate[{}]", at, i));
    } else if (key == "rotate_y_deg") {
      const float angle = finite_number(value, file, at + ".rotate_y_deg") * std::numbers::pi_v<float> / 180;
      m.topLeftCorner<3, 3>() = Eigen::AngleAxisf(angle, Eigen::Vector3f::UnitY()).toRotationMatrix();
    } else {
      fail(file, fmt::format("{} has an unknown key '{}' (expected translate, rotate_y_deg)", at, key));
    }
  }
  return m;
}

}  // namespace

std::vector<Eigen::Matrix4f> read_layout(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) fail(file, "cannot be read");
  json doc;
  try {
    doc = json::parse(in);
  } catch (const json::exception& e) {
    fail(file, fmt::format("is not JSON ({})", e.what()));
  }
  if (!doc.is_object() || !doc.contains("placements") || !doc["placements"].is_array() || doc.size() != 1) {
    fail(file, "expected {\"placements\": [...]} and nothing else");
  }
  std::vector<Eigen::Matrix4f> out;
  for (std::size_t k = 0; k < doc["placements"].size(); ++k)
    out.push_back(placement(doc["placements"][k], file, k));
  if (out.empty()) fail(file, "places no instance (expected at least one entry in placements)");
  return out;
}

std::vector<Eigen::Matrix4f> layout_placements(const std::vector<Eigen::Matrix4f>& layout,
                                               const std::filesystem::path& file, int count) {
  if (static_cast<int>(layout.size()) < count) {
    fail(file,
         fmt::format("places {} instances, {} are drawn (expected an entry for each)", layout.size(), count));
  }
  return {layout.begin(), layout.begin() + count};
}

}  // namespace phasecast::client
