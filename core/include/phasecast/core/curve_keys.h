#pragma once
// CURVE key files (ZeroMQ's CurveZMQ, docs/security.md). phasecast-keygen
// writes a pair for one party: NAME.key, the secret file (mode 0600), and
// NAME.pub, the public file handed to the other side. Both are text:
//
//   NAME.pub:  public = <40 Z85 characters>
//   NAME.key:  public = <40 Z85 characters>
//              secret = <40 Z85 characters>
//
// '#' starts a comment line. An allow-list file (the server's
// --allow-clients) is any number of public keys, one `public = ...` line or a
// bare 40-character key per line. Reading needs no ZeroMQ, so every tool can
// check its key options before opening a socket.

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::core {

// A key file that is missing, unreadable or malformed; one line naming the file.
class KeyFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline constexpr std::size_t kZ85KeyLength = 40;  // 32 bytes in Z85

struct CurveKeyPair {
  std::string public_z85;
  std::string secret_z85;
};

// Whether `key` is 40 characters of the Z85 alphabet.
bool is_z85_key(const std::string& key);

// Reads a secret file (both lines required).
CurveKeyPair read_secret_key_file(const std::filesystem::path& path);
// Reads the public key of a public or secret file.
std::string read_public_key_file(const std::filesystem::path& path);
// Reads an allow-list: every public key in the file, at least one.
std::vector<std::string> read_public_keys(const std::filesystem::path& path);

// Writes NAME.pub and NAME.key (0600) for `keys`; refuses to replace either.
void write_key_files(const std::filesystem::path& stem, const CurveKeyPair& keys);

}  // namespace phasecast::core
