#include "phasecast/precompute/appearance/transfer.h"

#include "phasecast/core/sh.h"
#include "phasecast/precompute/appearance/transfer_rays.h"

#include <fmt/format.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <mutex>
#include <numbers>
#include <thread>
#include <vector>

namespace phasecast::precompute {
namespace {

constexpr int kSh = core::kShCoefficients;
constexpr int kPerPoint = core::kShChannels * core::kShCoefficients;
constexpr int kMaxRays = 1 << 20;  // bounds memory: a direction and its 16 Y_k take 140 bytes

// A front-face hit kept from the first pass so that every bounce gathers from
// the same rays without casting them again (Sloan et al. 2002, §5).
struct CachedHit {
  std::array<std::uint32_t, 3> points;
  std::array<float, 3> weights;
  float cosine;  // n_p . omega_i
};

// Runs body(p) for p in [0, count) on `threads` threads (the caller is one of
// them and reports progress). Each p writes only its own outputs, so the
// result does not depend on the schedule.
template <class Body>
void parallel_points(long count, int threads, const char* stage, const TransferOptions& o, Body body) {
  constexpr long chunk = 16;
  std::atomic<long> next{0}, done{0};
  std::exception_ptr failure;
  std::mutex failure_mutex;
  auto work = [&](bool report) {
    for (;;) {
      const long begin = next.fetch_add(chunk);
      if (begin >= count) return;
      const long end = std::min(count, begin + chunk);
      try {
        for (long p = begin; p < end; ++p) body(p);
      } catch (...) {
        const std::lock_guard lock(failure_mutex);
        if (!failure) failure = std::current_exception();
        next = count;
      }
      const long finished = done += end - begin;
      if (report && o.progress && finished < count) o.progress(stage, finished, count);
    }
  };
  std::vector<std::jthread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work, false);
  work(true);
  pool.clear();  // joins
  if (failure) std::rethrow_exception(failure);
  if (o.progress) o.progress(stage, count, count);
}

void check_inputs(const MatrixXfR& P, const MatrixXuR& F, const MatrixXfR& N) {
  if (P.rows() == 0 || P.cols() != 3) {
    throw std::invalid_argument(
        fmt::format("transfer: positions must be S x 3 with S >= 1, got {} x {}", P.rows(), P.cols()));
  }
  if (N.rows() != P.rows() || N.cols() != 3) {
    throw std::invalid_argument(fmt::format("transfer: normals must be {} x 3 (one per point), got {} x {}",
                                            P.rows(), N.rows(), N.cols()));
  }
  if (F.rows() > 0 && F.cols() != 3) {
    throw std::invalid_argument(
        fmt::format("transfer: triangles must be F x 3, got {} x {}", F.rows(), F.cols()));
  }
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    if (!P.row(i).allFinite())
      throw std::invalid_argument(fmt::format("transfer: position {} is not finite", i));
    const float len = N.row(i).norm();
    if (!std::isfinite(len) || std::abs(len - 1) > 1e-3f) {
      throw std::invalid_argument(
          fmt::format("transfer: normal {} must be a unit vector, has length {}", i, len));
    }
  }
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int j = 0; j < 3; ++j) {
      if (F(f, j) >= P.rows()) {
        throw std::invalid_argument(
            fmt::format("transfer: triangle {} refers to point {}, expected < {}", f, F(f, j), P.rows()));
      }
    }
  }
}

// Offsets ray origins off the surface by a fraction of the scene size.
float ray_offset(const MatrixXfR& P) {
  const float diagonal = (P.colwise().maxCoeff() - P.colwise().minCoeff()).norm();
  return 1e-4f * std::max(diagonal, 1e-6f);
}

}  // namespace

TransferMode parse_transfer_mode(const std::string& name) {
  if (name == "unshadowed") return TransferMode::unshadowed;
  if (name == "shadowed") return TransferMode::shadowed;
  if (name == "interreflected") return TransferMode::interreflected;
  throw std::invalid_argument(
      fmt::format("unknown transfer mode '{}' (expected unshadowed, shadowed or interreflected)", name));
}

const char* transfer_mode_name(TransferMode mode) {
  switch (mode) {
    case TransferMode::unshadowed:
      return "unshadowed";
    case TransferMode::shadowed:
      return "shadowed";
    case TransferMode::interreflected:
      return "interreflected";
  }
  return "?";
}

void validate_transfer_options(const TransferOptions& o) {
  if (o.rays < 1 || o.rays > kMaxRays) {
    throw std::invalid_argument(fmt::format("transfer: rays must be in 1..{}, got {}", kMaxRays, o.rays));
  }
  if (o.bounces < 0)
    throw std::invalid_argument(fmt::format("transfer: bounces must be >= 0, got {}", o.bounces));
  if (o.threads < 0)
    throw std::invalid_argument(fmt::format("transfer: threads must be >= 0, got {}", o.threads));
  for (int c = 0; c < 3; ++c) {
    const float a = o.albedo[static_cast<size_t>(c)];
    if (!(a >= 0 && a <= 1)) {
      throw std::invalid_argument(fmt::format("transfer: albedo channel {} must be in [0, 1], got {}", c, a));
    }
  }
  if (o.point_albedo.size() > 0 && o.point_albedo.cols() != 3) {
    throw std::invalid_argument(fmt::format("transfer: point_albedo must be S x 3, got {} x {}",
                                            o.point_albedo.rows(), o.point_albedo.cols()));
  }
  for (Eigen::Index p = 0; p < o.point_albedo.rows(); ++p) {
    for (int c = 0; c < 3; ++c) {
      const float a = o.point_albedo(p, c);
      if (!(a >= 0 && a <= 1)) {
        throw std::invalid_argument(
            fmt::format("transfer: point_albedo of point {} channel {} must be in [0, 1], got {}", p, c, a));
      }
    }
  }
}

MatrixXfR sphere_directions(int count) {
  if (count < 1)
    throw std::invalid_argument(fmt::format("sphere_directions: count must be >= 1, got {}", count));
  // Spherical Fibonacci lattice: z uniform in (-1, 1) (equal-area bands), the
  // azimuth advancing by the golden angle.
  const double golden_angle = std::numbers::pi * (3 - std::sqrt(5.0));
  MatrixXfR d(count, 3);
  for (int i = 0; i < count; ++i) {
    const double z = 1 - (2 * i + 1.0) / count;
    const double r = std::sqrt(std::max(0.0, 1 - z * z));
    const double phi = golden_angle * i;
    d(i, 0) = static_cast<float>(r * std::cos(phi));
    d(i, 1) = static_cast<float>(r * std::sin(phi));
    d(i, 2) = static_cast<float>(z);
  }
  return d;
}

namespace {

using ShTable = Eigen::Matrix<double, Eigen::Dynamic, kSh, Eigen::RowMajor>;
using Transfer = RowMatrix<double>;  // S x 48, row-major: a gather reads whole rows

// Y_k(omega_i) of the fixed direction set, computed once.
ShTable sh_table(const MatrixXfR& dirs) {
  ShTable Y(dirs.rows(), kSh);
  for (Eigen::Index i = 0; i < dirs.rows(); ++i) {
    const auto y = core::sh_basis(dirs(i, 0), dirs(i, 1), dirs(i, 2));
    for (int k = 0; k < kSh; ++k) Y(i, k) = y[static_cast<size_t>(k)];
  }
  return Y;
}

// Everything one transfer run shares between its passes.
struct TransferRun {
  const MatrixXfR& P;
  const MatrixXfR& N;
  const TransferOptions& o;
  int threads = 1;
  MatrixXfR dirs{};                   // the fixed direction set, rays x 3
  ShTable Y{};                        // Y_k of each direction
  RowMatrix<double> weight{};         // S x 3: (rho_pc / pi) (4 pi / rays), the weight of one direction
  const RayCaster* caster = nullptr;  // null: nothing to cast against (unshadowed, or no triangles)
  bool gather = false;                // interreflected with bounces: cache front-face hits
  float offset = 0;                   // ray origins leave the surface along the normal by this
};

// Direct light: T_pck = (rho_c/pi) sum_i (4pi/N) V(omega_i) max(0, n.omega_i) Y_k(omega_i)   (§4.1).
Transfer direct_light(const TransferRun& r, std::vector<std::vector<CachedHit>>& hits) {
  Transfer T(r.P.rows(), kPerPoint);
  parallel_points(r.P.rows(), r.threads, "direct", r.o, [&](long p) {
    const std::array<float, 3> n{r.N(p, 0), r.N(p, 1), r.N(p, 2)};
    const std::array<float, 3> origin{r.P(p, 0) + r.offset * n[0], r.P(p, 1) + r.offset * n[1],
                                      r.P(p, 2) + r.offset * n[2]};
    Eigen::Matrix<double, 1, kSh> sum = Eigen::Matrix<double, 1, kSh>::Zero();
    for (Eigen::Index i = 0; i < r.dirs.rows(); ++i) {
      const std::array<float, 3> w{r.dirs(i, 0), r.dirs(i, 1), r.dirs(i, 2)};
      const float cosine = n[0] * w[0] + n[1] * w[1] + n[2] * w[2];
      if (cosine <= 0) continue;
      bool visible = true;
      if (r.gather) {
        const RayHit hit = r.caster->closest(origin, w);
        visible = !hit.hit;
        if (hit.front) hits[static_cast<size_t>(p)].push_back({hit.points, hit.weights, cosine});
      } else if (r.caster) {
        visible = !r.caster->occluded(origin, w);
      }
      if (visible) sum += cosine * r.Y.row(i);
    }
    for (int c = 0; c < 3; ++c) T.block<1, kSh>(p, kSh * c) = r.weight(p, c) * sum;
  });
  return T;
}

// Bounce b gathers bounce b-1 at the cached hits, interpolated over the hit
// triangle:  T^b_p = (rho/pi) sum_i (4pi/N) max(0, n.omega_i) T^{b-1}(hit_i).
Transfer next_bounce(const TransferRun& r, const std::vector<std::vector<CachedHit>>& hits,
                     const Transfer& previous, const std::string& stage) {
  Transfer T(previous.rows(), kPerPoint);
  parallel_points(previous.rows(), r.threads, stage.c_str(), r.o, [&](long p) {
    Eigen::Matrix<double, 1, kPerPoint> sum = Eigen::Matrix<double, 1, kPerPoint>::Zero();
    for (const CachedHit& h : hits[static_cast<size_t>(p)]) {
      for (int j = 0; j < 3; ++j) {
        sum +=
            (h.cosine * h.weights[static_cast<size_t>(j)]) * previous.row(h.points[static_cast<size_t>(j)]);
      }
    }
    for (int c = 0; c < 3; ++c) {
      T.block<1, kSh>(p, kSh * c) = r.weight(p, c) * sum.segment<kSh>(kSh * c);
    }
  });
  return T;
}

}  // namespace

MatrixXfR compute_transfer(const MatrixXfR& P, const MatrixXuR& F, const MatrixXfR& N,
                           const TransferOptions& o) {
  validate_transfer_options(o);
  check_inputs(P, F, N);
  if (o.point_albedo.size() > 0 && o.point_albedo.rows() != P.rows()) {
    throw std::invalid_argument(fmt::format("transfer: point_albedo has {} rows, expected one per point ({})",
                                            o.point_albedo.rows(), P.rows()));
  }
  std::unique_ptr<RayCaster> caster;
  if (o.mode != TransferMode::unshadowed && F.rows() > 0) caster = std::make_unique<RayCaster>(P, F);
  TransferRun run{P, N, o};
  run.threads =
      o.threads > 0 ? o.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  run.dirs = sphere_directions(o.rays);
  run.caster = caster.get();
  run.gather = o.mode == TransferMode::interreflected && o.bounces > 0 && caster;
  run.offset = ray_offset(P);
  run.Y = sh_table(run.dirs);
  run.weight.resize(P.rows(), 3);
  for (Eigen::Index p = 0; p < P.rows(); ++p) {
    for (int c = 0; c < 3; ++c) {
      const double rho = o.point_albedo.size() > 0 ? o.point_albedo(p, c) : o.albedo[static_cast<size_t>(c)];
      run.weight(p, c) = 4.0 * rho / o.rays;
    }
  }

  std::vector<std::vector<CachedHit>> hits(run.gather ? static_cast<size_t>(P.rows()) : 0);
  Transfer bounce = direct_light(run, hits);
  Transfer total = bounce;
  for (int b = 1; run.gather && b <= o.bounces; ++b) {
    bounce = next_bounce(run, hits, bounce, fmt::format("bounce {}/{}", b, o.bounces));
    total += bounce;
  }
  return total.cast<float>();
}

}  // namespace phasecast::precompute
