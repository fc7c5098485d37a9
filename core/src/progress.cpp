#include "phasecast/core/progress.h"

#include <fmt/format.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>

namespace phasecast::core {
namespace {
std::atomic<bool> g_muted{false};
}  // namespace

void ProgressBar::mute_all() {
  g_muted = true;
}

ProgressBar::ProgressBar(std::string stage, std::FILE* out)
    : stage_(std::move(stage)),
      out_(out),
      tty_(::isatty(::fileno(out)) != 0),
      start_(std::chrono::steady_clock::now()) {}

void ProgressBar::restart(std::string stage) {
  finish();
  stage_ = std::move(stage);
  last_decile_ = -1;
  drawn_ = false;
  first_done_ = -1;
  start_ = std::chrono::steady_clock::now();
}

void ProgressBar::update(long done, long total, const std::string& detail) {
  if (total <= 0 || g_muted) return;
  if (first_done_ < 0) first_done_ = std::max(0L, done - 1);  // all but the first unit came before this run
  const double fraction = static_cast<double>(done) / static_cast<double>(total);
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const long fresh = done - first_done_;
  const double eta =
      fresh > 0 ? elapsed * static_cast<double>(total - done) / static_cast<double>(fresh) : 0.0;
  const std::string tail = detail.empty() ? std::string() : ", " + detail;
  if (tty_) {
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(fraction * kWidth);
    fmt::print(out_, "\r{} [{}{}] {}/{} {:3.0f}%{} ETA {:.0f}s \x1b[K", stage_,
               std::string(static_cast<size_t>(filled), '#'),
               std::string(static_cast<size_t>(kWidth - filled), '.'), done, total, 100 * fraction, tail,
               eta);
    drawn_ = true;
  } else {
    const int decile = static_cast<int>(fraction * 10);
    if (decile == last_decile_) return;
    last_decile_ = decile;
    fmt::print(out_, "{}: {}/{} ({:.0f}%){}, elapsed {:.1f}s, ETA {:.0f}s\n", stage_, done, total,
               100 * fraction, tail, elapsed, eta);
  }
  std::fflush(out_);
}

void ProgressBar::finish() {
  if (tty_ && drawn_) fmt::print(out_, "\n");
  drawn_ = false;
}

}  // namespace phasecast::core
