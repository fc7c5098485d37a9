#include "phasecast/core/progress.h"

#include <fmt/format.h>

#include <unistd.h>

namespace phasecast::core {

ProgressBar::ProgressBar(std::string stage, std::FILE* out)
    : stage_(std::move(stage)),
      out_(out),
      tty_(::isatty(::fileno(out)) != 0),
      start_(std::chrono::steady_clock::now()) {}

void ProgressBar::update(int done, int total) {
  if (total <= 0) return;
  const double fraction = static_cast<double>(done) / total;
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double eta = done > 0 ? elapsed * (total - done) / done : 0.0;
  if (tty_) {
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(fraction * kWidth);
    fmt::print(out_, "\r{} [{}{}] {}/{} {:3.0f}% ETA {:.0f}s ", stage_,
               std::string(static_cast<size_t>(filled), '#'),
               std::string(static_cast<size_t>(kWidth - filled), '.'), done, total, 100 * fraction, eta);
    drawn_ = true;
  } else {
    const int decile = static_cast<int>(fraction * 10);
    if (decile == last_decile_) return;
    last_decile_ = decile;
    fmt::print(out_, "{}: {}/{} ({:.0f}%), elapsed {:.1f}s, ETA {:.0f}s\n", stage_, done, total,
               100 * fraction, elapsed, eta);
  }
  std::fflush(out_);
}

void ProgressBar::finish() {
  if (tty_ && drawn_) fmt::print(out_, "\n");
}

}  // namespace phasecast::core
