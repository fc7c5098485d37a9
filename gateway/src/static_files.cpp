#include "phasecast/gateway/static_files.h"

#include <algorithm>
#include <array>
#include <utility>

namespace phasecast::gateway {

std::optional<std::filesystem::path> resolve_static(const std::filesystem::path& web_root,
                                                    std::string_view target) {
  const auto query = target.find_first_of("?#");
  if (query != std::string_view::npos) target = target.substr(0, query);
  if (!target.starts_with('/')) return {};
  if (target == "/") target = "/index.html";
  const auto allowed = [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '/' ||
           c == '.' || c == '-' || c == '_';
  };
  if (!std::all_of(target.begin(), target.end(), allowed)) return {};
  // No "." or ".." segments and no hidden files: every segment starts with a
  // letter, digit or underscore.
  for (std::size_t i = 0; i < target.size(); ++i) {
    if (target[i] == '/' && (i + 1 == target.size() || target[i + 1] == '.' || target[i + 1] == '/'))
      return {};
  }
  return web_root / std::filesystem::path(target.substr(1));
}

std::string content_type(const std::filesystem::path& file) {
  static const std::array<std::pair<const char*, const char*>, 10> types = {{
      {".html", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},
      {".json", "application/json"},
      {".map", "application/json"},
      {".png", "image/png"},
      {".svg", "image/svg+xml"},
      {".ico", "image/x-icon"},
      {".txt", "text/plain; charset=utf-8"},
  }};
  const auto ext = file.extension().string();
  for (const auto& [e, type] : types) {
    if (ext == e) return type;
  }
  return "application/octet-stream";
}

std::filesystem::path default_web_root(const std::filesystem::path& executable) {
  std::error_code ec;
  auto bin = std::filesystem::weakly_canonical(executable, ec).parent_path();
  const auto build_tree = bin.parent_path() / "web";
  if (std::filesystem::exists(build_tree / "index.html", ec)) return build_tree;
  return bin.parent_path() / "share" / "phasecast" / "web";
}

}  // namespace phasecast::gateway
