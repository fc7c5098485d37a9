#include "phasecast/core/curve_keys.h"

#include <fmt/format.h>

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <optional>
#include <string_view>

namespace phasecast::core {
namespace {

constexpr std::string_view kZ85Alphabet =
    "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.-:+=^!/*?&<>()[]{}@%$#";

std::string trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) return {};
  const auto e = s.find_last_not_of(" \t\r");
  return std::string(s.substr(b, e - b + 1));
}

struct KeyLine {
  std::string field;  // "public", "secret" or "" for a bare key
  std::string key;
};

// Every non-comment line of `path` as (field, key); throws for a line that is
// neither `field = key` nor a bare key, and for keys that are not Z85.
std::vector<KeyLine> read_key_lines(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) {
    throw KeyFileError(fmt::format("key file '{}' cannot be read: {}", path.string(), std::strerror(errno)));
  }
  std::vector<KeyLine> lines;
  std::string raw;
  for (int n = 1; std::getline(in, raw); ++n) {
    const std::string line = trim(raw);
    if (line.empty() || line[0] == '#') continue;
    KeyLine kl;
    if (const auto eq = line.find('='); eq != std::string::npos && line.size() != kZ85KeyLength) {
      kl.field = trim(std::string_view(line).substr(0, eq));
      kl.key = trim(std::string_view(line).substr(eq + 1));
    } else {
      kl.key = line;
    }
    if ((kl.field != "" && kl.field != "public" && kl.field != "secret") || !is_z85_key(kl.key)) {
      throw KeyFileError(fmt::format(
          "key file '{}' line {}: expected 'public = <key>' or 'secret = <key>' with a {}-character Z85 key",
          path.string(), n, kZ85KeyLength));
    }
    lines.push_back(std::move(kl));
  }
  return lines;
}

std::optional<std::string> field(const std::vector<KeyLine>& lines, const std::string& name) {
  for (const auto& l : lines)
    if (l.field == name) return l.key;
  return std::nullopt;
}

void write_exclusive(const std::filesystem::path& path, const std::string& text, mode_t mode) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, mode);
  if (fd < 0) {
    throw KeyFileError(fmt::format("cannot create key file '{}': {} (existing keys are never replaced)",
                                   path.string(), std::strerror(errno)));
  }
  const bool ok =
      ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size()) && ::fsync(fd) == 0;
  ::close(fd);
  if (!ok) throw KeyFileError(fmt::format("cannot write key file '{}'", path.string()));
}

}  // namespace

bool is_z85_key(const std::string& key) {
  return key.size() == kZ85KeyLength && key.find_first_not_of(kZ85Alphabet) == std::string::npos;
}

CurveKeyPair read_secret_key_file(const std::filesystem::path& path) {
  const auto lines = read_key_lines(path);
  const auto pub = field(lines, "public");
  const auto sec = field(lines, "secret");
  if (!pub || !sec) {
    throw KeyFileError(fmt::format(
        "key file '{}' is not a secret key file (expected 'public = ...' and 'secret = ...' lines, as "
        "phasecast-keygen writes in NAME.key)",
        path.string()));
  }
  return {*pub, *sec};
}

std::string read_public_key_file(const std::filesystem::path& path) {
  const auto lines = read_key_lines(path);
  if (const auto pub = field(lines, "public")) return *pub;
  if (lines.size() == 1 && lines[0].field.empty()) return lines[0].key;
  throw KeyFileError(
      fmt::format("key file '{}' holds no public key (expected a 'public = <key>' line)", path.string()));
}

std::vector<std::string> read_public_keys(const std::filesystem::path& path) {
  std::vector<std::string> keys;
  for (const auto& l : read_key_lines(path)) {
    if (l.field == "secret") {
      throw KeyFileError(fmt::format(
          "allow-list '{}' holds a secret key (expected only public keys; hand out NAME.pub, never NAME.key)",
          path.string()));
    }
    keys.push_back(l.key);
  }
  if (keys.empty()) throw KeyFileError(fmt::format("allow-list '{}' holds no public key", path.string()));
  return keys;
}

void write_key_files(const std::filesystem::path& stem, const CurveKeyPair& keys) {
  auto pub = stem;
  pub += ".pub";
  auto sec = stem;
  sec += ".key";
  const std::string header = "# phasecast CURVE key (docs/security.md)\n";
  write_exclusive(sec, header + "public = " + keys.public_z85 + "\nsecret = " + keys.secret_z85 + "\n", 0600);
  write_exclusive(pub, header + "public = " + keys.public_z85 + "\n", 0644);
}

}  // namespace phasecast::core
