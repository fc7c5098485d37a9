#pragma once
// The page's files, served from the web root (the npm build's output,
// web/build.mjs): request targets are mapped to files inside it only.

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace phasecast::gateway {

// The file for an HTTP target ("/", "/app.js?v=1"): "/" is index.html; the
// query is ignored. nullopt for targets that could leave the root or name
// something odd (.., %, backslashes, hidden files), whether or not it exists.
std::optional<std::filesystem::path> resolve_static(const std::filesystem::path& web_root,
                                                    std::string_view target);

// Content-Type by extension; application/octet-stream when unknown.
std::string content_type(const std::filesystem::path& file);

// The web root next to the gateway binary: <bin>/../web (the build tree's
// build/web, an install's share/phasecast/web).
std::filesystem::path default_web_root(const std::filesystem::path& executable);

}  // namespace phasecast::gateway
