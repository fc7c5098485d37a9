// HDF5 reading and writing of the scene package (docs/package-format.md).
// Reading first checks every dataset's presence, rank, exact dtype and
// declared size against what the file stores (h5::Reader::require), then the
// shape rules on those extents (check_shapes), and only then allocates and
// reads; indices and finiteness are checked by validate_package() so that the
// writer enforces the very same rules.

#include "package_fidelity.h"
#include "package_shapes.h"
#include "package_upgrade.h"
#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/kinematics_rows.h"
#include "phasecast/core/package.h"

#include <fmt/format.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>

namespace phasecast::core {
namespace {

using Reader = h5::Reader;

// The version the file was written in: today's, or one package_upgrade.h reads.
int stored_format_version(const Reader& r) {
  // Orbit stores and transfer files name their format; packages do not.
  if (r.file().has_attribute("format")) {
    r.fail("/@format",
           fmt::format("a '{}' file, not a scene package (expected the output of phasecast-precompute "
                       "run or reduce)",
                       r.text("format")));
  }
  const double version = r.number("format_version");
  if (version != kFormatVersion && version != kOldestFormatVersion) {
    r.fail("/@format_version", fmt::format("unknown format_version {} (this build reads {} to {})", version,
                                           kOldestFormatVersion, kFormatVersion));
  }
  return static_cast<int>(version);
}

// The [view] attributes besides the camera; each optional.
void read_view(const Reader& r, PackageAttributes& a) {
  const auto& f = r.file();
  if (f.has_attribute("floor")) a.floor = r.number("floor") != 0;
  if (f.has_attribute("floor_height")) {
    a.floor_height = static_cast<float>(r.number("floor_height"));
    if (!std::isfinite(*a.floor_height)) r.fail("/@floor_height", "expected a finite height");
  }
  if (f.has_attribute("light")) a.light = r.text("light");
  if (f.has_attribute("exposure")) {
    a.exposure = static_cast<float>(r.number("exposure"));
    if (!(*a.exposure > 0) || !std::isfinite(*a.exposure)) r.fail("/@exposure", "expected a positive number");
  }
}

// Read into today's version: the in-memory package knows no other.
PackageAttributes read_attributes(const Reader& r) {
  PackageAttributes a;
  a.format_version = kFormatVersion;
  a.scene = r.text("scene");
  a.dt = r.number("dt");
  a.beta = r.number("beta");
  a.blend_lambda = r.number("blend_lambda");
  a.eps_u = r.number("eps_u");
  a.eps_a = r.number("eps_a");
  if (r.file().has_attribute("camera")) {
    const auto c = r.floats("camera");
    if (c.size() != 10)
      r.fail("/@camera", fmt::format("expected 10 floats (eye, target, up, fov_y_deg), got {}", c.size()));
    std::array<float, 10> cam{};
    std::copy(c.begin(), c.end(), cam.begin());
    a.camera = cam;
  }
  read_view(r, a);
  return a;
}

struct DatasetSpec {
  const char* name;
  h5::Dtype dtype;
  size_t rank;
};

using h5::Dtype;
constexpr DatasetSpec kRequired[] = {
    {"/mesh/rest_positions", Dtype::f32, 2},   {"/mesh/triangles", Dtype::u32, 2},
    {"/mesh/normals", Dtype::f32, 2},          {"/mesh/deformable", Dtype::u8, 1},
    {"/mesh/attached", Dtype::u8, 1},          {"/palette/names", Dtype::string, 1},
    {"/palette/alpha_impulse", Dtype::f32, 2}, {"/palette/alpha_forcing", Dtype::f32, 2},
    {"/palette/transitions", Dtype::u8, 2},    {"/palette/on_end", Dtype::i32, 1},
    {"/palette/kinematics", Dtype::f32, 2},    {"/reduction/mean_shape", Dtype::f32, 1},
    {"/reduction/U_u", Dtype::f32, 2},         {"/reduction/singular_values", Dtype::f32, 1},
    {"/reduction/rel_error", Dtype::f32, 1},   {"/portrait/q_u", Dtype::f32, 2},
    {"/portrait/qdot_u", Dtype::f32, 2},       {"/portrait/irf_start", Dtype::i32, 1},
    {"/portrait/irf_length", Dtype::i32, 1},   {"/portrait/irf_palette", Dtype::i32, 1},
    {"/portrait/nearest_irf", Dtype::i32, 2},
};
constexpr DatasetSpec kOptional[] = {
    {"/palette/group", Dtype::i32, 1},
    {"/palette/max_in_a_row", Dtype::i32, 1},
    {"/portrait/support", Dtype::f32, 2},
};
// Required when the /appearance group exists.
constexpr DatasetSpec kAppearance[] = {
    {"/portrait/q_a", Dtype::f32, 2},
    {"/appearance/mean_transfer", Dtype::f32, 1},
    {"/appearance/U_a", Dtype::f32, 2},
    {"/appearance/singular_values", Dtype::f32, 1},
    {"/appearance/rel_error", Dtype::f32, 1},
    {"/appearance/cluster_nodes", Dtype::i32, 1},
    {"/appearance/nrbf_centers", Dtype::f32, 2},
    {"/appearance/nrbf_weights", Dtype::f32, 2},
    {"/appearance/nrbf_widths", Dtype::f32, 1},
    {"/appearance/nrbf_regularization", Dtype::f32, 1},
};
// Optional inside /appearance: the interpolant's name and parameters, the
// paper's r_a and how the transfer was sampled.
constexpr DatasetSpec kAppearanceOptional[] = {
    {"/appearance/interpolant", Dtype::string, 1},
    {"/appearance/interpolant_parameters", Dtype::f32, 1},
    {"/appearance/paper_rank", Dtype::i32, 1},
    {"/appearance/transfer_sampling", Dtype::i32, 1},
    {"/appearance/transfer_weighting", Dtype::string, 1},
};

// The held-out figures' extents as the file declares them (absent ones absent).
void add_held_out_datasets(const Reader& r, PackageShapes& s) {
  const auto add = [&](const char* name, Dtype dtype) {
    if (r.file().exists(name)) s[name] = r.require(name, dtype, 1).dims;
  };
  add(kHeldOutNodes, Dtype::i32);
  for (const auto& f : kHeldOutFigures) add(f.name, Dtype::f32);
  for (const auto& f : kOptionalHeldOutFigures) add(f.name, Dtype::f32);
  for (const auto& f : kHeldOutSpreads) add(f.name, Dtype::f32);
  add(kHeldOutCurve, Dtype::f32);
}

// The extents the file declares, each checked against what the file stores,
// with the defaults read_from() fills in for absent optional datasets.
// `upgraded_held_out`: the held-out figures an older version's layout held,
// read by the upgrade, whose extents stand for the datasets today's holds.
PackageShapes declared_shapes(const Reader& r, const std::optional<HeldOutFigures>& upgraded_held_out) {
  PackageShapes s;
  const auto add = [&](const DatasetSpec& d) { s[d.name] = r.require(d.name, d.dtype, d.rank).dims; };
  for (const auto& d : kRequired) add(d);
  for (const auto& d : kOptional) {
    if (r.file().exists(d.name)) add(d);
  }
  if (r.file().exists("/appearance")) {
    for (const auto& d : kAppearance) add(d);
    for (const auto& d : kAppearanceOptional) {
      if (r.file().exists(d.name)) add(d);
    }
    if (upgraded_held_out) {
      add_held_out_shapes(*upgraded_held_out, s);
    } else {
      add_held_out_datasets(r, s);
    }
  } else {
    s["/portrait/q_a"] = {s["/portrait/q_u"][0], 0};
  }
  add_fidelity_datasets(r, s);
  s.try_emplace("/palette/group", s["/palette/names"]);
  s.try_emplace("/palette/max_in_a_row", s["/palette/names"]);
  return s;
}

ImpulsePalette read_palette(const Reader& r) {
  ImpulsePalette p;
  p.names = r.strings("/palette/names");
  p.alpha_impulse = r.matrix<float>("/palette/alpha_impulse");
  p.alpha_forcing = r.matrix<float>("/palette/alpha_forcing");
  p.transitions = r.matrix<std::uint8_t>("/palette/transitions");
  p.on_end = r.vector<std::int32_t>("/palette/on_end");
  p.kinematics = kinematics_from_rows(r.matrix<float>("/palette/kinematics"));
  // Run limits (max_in_a_row) came with the playback-fidelity work; packages
  // written before them have none: every entry its own group, no limit.
  const auto D = static_cast<std::int32_t>(p.names.size());
  if (r.file().exists("/palette/group")) {
    p.group = r.vector<std::int32_t>("/palette/group");
  } else {
    for (std::int32_t d = 0; d < D; ++d) p.group.push_back(d);
  }
  p.max_in_a_row = r.file().exists("/palette/max_in_a_row") ? r.vector<std::int32_t>("/palette/max_in_a_row")
                                                            : std::vector<std::int32_t>(p.names.size(), 0);
  return p;
}

// Today's held-out figures, after check_shapes() (absent: not measured).
std::optional<HeldOutFigures> read_held_out(const Reader& r) {
  if (!r.file().exists(kHeldOutNodes)) return std::nullopt;
  HeldOutFigures h;
  h.nodes = r.vector<std::int32_t>(kHeldOutNodes);
  const auto figure = [&r](const char* name) { return r.column<float>(name, 1)[0]; };
  for (const auto& f : kHeldOutFigures) h.*f.member = figure(f.name);
  for (const auto& f : kOptionalHeldOutFigures)
    if (r.file().exists(f.name)) h.*f.member = figure(f.name);
  for (const auto& f : kHeldOutSpreads) {
    if (r.file().exists(f.name)) {
      const VectorXf v = r.column<float>(f.name, 2);
      h.*f.member = Percentiles{v[0], v[1]};
    }
  }
  if (r.file().exists(kHeldOutCurve)) h.truncation_curve = r.column<float>(kHeldOutCurve);
  return h;
}

Appearance read_appearance(const Reader& r) {
  Appearance a;
  a.mean_transfer = r.column<float>("/appearance/mean_transfer");
  a.U_a = r.matrix<float>("/appearance/U_a");
  a.singular_values = r.column<float>("/appearance/singular_values");
  a.rel_error = r.column<float>("/appearance/rel_error");
  a.cluster_nodes = r.vector<std::int32_t>("/appearance/cluster_nodes");
  a.nrbf_centers = r.matrix<float>("/appearance/nrbf_centers");
  a.nrbf_weights = r.matrix<float>("/appearance/nrbf_weights");
  a.nrbf_widths = r.column<float>("/appearance/nrbf_widths");
  a.nrbf_regularization = r.column<float>("/appearance/nrbf_regularization", 1)[0];
  const auto exists = [&r](const char* name) { return r.file().exists(name); };
  if (exists("/appearance/interpolant")) a.interpolant = r.strings("/appearance/interpolant").at(0);
  if (exists("/appearance/interpolant_parameters"))
    a.interpolant_parameters = r.column<float>("/appearance/interpolant_parameters");
  if (exists("/appearance/transfer_weighting"))
    a.transfer_weighting = r.strings("/appearance/transfer_weighting").at(0);
  if (exists("/appearance/paper_rank")) a.paper_rank = r.vector<std::int32_t>("/appearance/paper_rank").at(0);
  if (exists("/appearance/transfer_sampling")) {
    const auto sampling = r.vector<std::int32_t>("/appearance/transfer_sampling");
    a.transfer_rays = sampling.at(0);
    a.transfer_bounces = sampling.at(1);
  }
  return a;
}

// Reads only after check_shapes() has accepted every extent, so that each
// allocation below is bounded by the shape rules and the file's size.
ScenePackage read_from(const Reader& r) {
  ScenePackage pkg;
  const int version = stored_format_version(r);
  pkg.attributes = read_attributes(r);
  const bool appearance = r.file().exists("/appearance");
  std::optional<HeldOutFigures> upgraded_held_out;
  if (appearance && version < kFormatVersion) upgraded_held_out = upgrade_held_out(r, version);
  check_shapes(declared_shapes(r, upgraded_held_out), r.source());

  pkg.mesh.rest_positions = r.matrix<float>("/mesh/rest_positions");
  pkg.mesh.triangles = r.matrix<std::uint32_t>("/mesh/triangles");
  pkg.mesh.normals = r.matrix<float>("/mesh/normals");
  pkg.mesh.deformable = r.vector<std::uint8_t>("/mesh/deformable");
  pkg.mesh.attached = r.vector<std::uint8_t>("/mesh/attached");

  pkg.palette = read_palette(r);

  pkg.reduction.mean_shape = r.column<float>("/reduction/mean_shape");
  pkg.reduction.U_u = r.matrix<float>("/reduction/U_u");
  pkg.reduction.singular_values = r.column<float>("/reduction/singular_values");
  pkg.reduction.rel_error = r.column<float>("/reduction/rel_error");

  auto& pp = pkg.portrait;
  pp.q_u = r.matrix<float>("/portrait/q_u");
  pp.qdot_u = r.matrix<float>("/portrait/qdot_u");
  pp.irf_start = r.vector<std::int32_t>("/portrait/irf_start");
  pp.irf_length = r.vector<std::int32_t>("/portrait/irf_length");
  pp.irf_palette = r.vector<std::int32_t>("/portrait/irf_palette");
  pp.nearest_irf = r.matrix<std::int32_t>("/portrait/nearest_irf");
  if (r.file().exists("/portrait/support")) pp.support = r.matrix<float>("/portrait/support");

  if (appearance) {
    pkg.appearance = read_appearance(r);
    pkg.appearance->held_out = version < kFormatVersion ? upgraded_held_out : read_held_out(r);
    pp.q_a = r.matrix<float>("/portrait/q_a");
  } else {
    pp.q_a.resize(pp.q_u.rows(), 0);
  }
  pkg.fidelity = read_fidelity(r);
  return pkg;
}

// ---- writing -------------------------------------------------------------------

void write_held_out(h5::File& f, const HeldOutFigures& h) {
  const auto figure = [&f](const char* name, float v) { f.write(name, std::vector<float>{v}); };
  f.write(kHeldOutNodes, h.nodes);
  for (const auto& fig : kHeldOutFigures) figure(fig.name, h.*fig.member);
  for (const auto& fig : kOptionalHeldOutFigures)
    if (const auto& v = h.*fig.member) figure(fig.name, *v);
  for (const auto& fig : kHeldOutSpreads)
    if (const auto& v = h.*fig.member) f.write(fig.name, std::vector<float>{v->p10, v->p90});
  if (h.truncation_curve.size() > 0) f.write(kHeldOutCurve, h.truncation_curve);
}

void write_to(h5::File& f, const ScenePackage& pkg) {
  const auto& a = pkg.attributes;
  f.write_attribute("format_version", static_cast<std::int32_t>(kFormatVersion));
  f.write_attribute("scene", a.scene);
  f.write_attribute("dt", a.dt);
  f.write_attribute("beta", a.beta);
  f.write_attribute("blend_lambda", a.blend_lambda);
  f.write_attribute("eps_u", a.eps_u);
  f.write_attribute("eps_a", a.eps_a);
  if (a.camera) f.write_attribute("camera", std::vector<float>(a.camera->begin(), a.camera->end()));
  if (!a.floor) f.write_attribute("floor", std::int32_t{0});
  if (a.floor_height) f.write_attribute("floor_height", *a.floor_height);
  if (!a.light.empty()) f.write_attribute("light", a.light);
  if (a.exposure) f.write_attribute("exposure", *a.exposure);

  f.write("/mesh/rest_positions", pkg.mesh.rest_positions);
  f.write("/mesh/triangles", pkg.mesh.triangles);
  f.write("/mesh/normals", pkg.mesh.normals);
  f.write("/mesh/deformable", pkg.mesh.deformable);
  f.write("/mesh/attached", pkg.mesh.attached);

  f.write_strings("/palette/names", pkg.palette.names);
  f.write("/palette/alpha_impulse", pkg.palette.alpha_impulse);
  f.write("/palette/alpha_forcing", pkg.palette.alpha_forcing);
  f.write("/palette/transitions", pkg.palette.transitions);
  f.write("/palette/on_end", pkg.palette.on_end);
  f.write("/palette/group", pkg.palette.group);
  f.write("/palette/max_in_a_row", pkg.palette.max_in_a_row);
  f.write("/palette/kinematics", kinematics_to_rows(pkg.palette.kinematics));
  f.write_attribute_on("/palette/kinematics", "columns", kKinematicsColumnNames);

  f.write("/reduction/mean_shape", pkg.reduction.mean_shape);
  f.write("/reduction/U_u", pkg.reduction.U_u);
  f.write("/reduction/singular_values", pkg.reduction.singular_values);
  f.write("/reduction/rel_error", pkg.reduction.rel_error);

  const auto& pp = pkg.portrait;
  f.write("/portrait/q_u", pp.q_u);
  f.write("/portrait/qdot_u", pp.qdot_u);
  f.write("/portrait/irf_start", pp.irf_start);
  f.write("/portrait/irf_length", pp.irf_length);
  f.write("/portrait/irf_palette", pp.irf_palette);
  f.write("/portrait/nearest_irf", pp.nearest_irf);
  if (pp.support.rows() > 0) f.write("/portrait/support", pp.support);

  if (const auto& ap = pkg.appearance) {
    f.write("/portrait/q_a", pp.q_a);
    f.write("/appearance/mean_transfer", ap->mean_transfer);
    f.write("/appearance/U_a", ap->U_a);
    f.write("/appearance/singular_values", ap->singular_values);
    f.write("/appearance/rel_error", ap->rel_error);
    f.write("/appearance/cluster_nodes", ap->cluster_nodes);
    f.write("/appearance/nrbf_centers", ap->nrbf_centers);
    f.write("/appearance/nrbf_weights", ap->nrbf_weights);
    f.write("/appearance/nrbf_widths", ap->nrbf_widths);
    f.write("/appearance/nrbf_regularization", VectorXf(VectorXf::Constant(1, ap->nrbf_regularization)));
    f.write_strings("/appearance/interpolant", {ap->interpolant});
    f.write("/appearance/interpolant_parameters", ap->interpolant_parameters);
    f.write_strings("/appearance/transfer_weighting", {ap->transfer_weighting});
    if (ap->held_out) write_held_out(f, *ap->held_out);
    if (ap->paper_rank > 0) f.write("/appearance/paper_rank", std::vector<std::int32_t>{ap->paper_rank});
    if (ap->transfer_rays > 0)
      f.write("/appearance/transfer_sampling",
              std::vector<std::int32_t>{ap->transfer_rays, ap->transfer_bounces});
  }
  if (pkg.fidelity) write_fidelity(f, *pkg.fidelity);
}

}  // namespace

MatrixXfR kinematics_to_rows(const std::vector<SupportKinematics>& kinematics) {
  MatrixXfR k(static_cast<Eigen::Index>(kinematics.size()), kKinematicsColumns);
  for (Eigen::Index i = 0; i < k.rows(); ++i) {
    const auto& s = kinematics[static_cast<size_t>(i)];
    k.row(i) << s.axis[0], s.axis[1], s.axis[2], s.pivot[0], s.pivot[1], s.pivot[2],
        s.rotational ? 1.0f : 0.0f, s.rate, s.range_min, s.range_max, s.pulse_tau;
  }
  return k;
}

std::vector<SupportKinematics> kinematics_from_rows(const MatrixXfR& k) {
  std::vector<SupportKinematics> out;
  for (Eigen::Index i = 0; i < k.rows(); ++i) {
    SupportKinematics s;
    s.axis = {k(i, 0), k(i, 1), k(i, 2)};
    s.pivot = {k(i, 3), k(i, 4), k(i, 5)};
    s.rotational = k(i, 6) != 0.0f;
    s.rate = k(i, 7);
    s.range_min = k(i, 8);
    s.range_max = k(i, 9);
    s.pulse_tau = k(i, 10);
    out.push_back(s);
  }
  return out;
}

namespace {

ScenePackage read_in_process(const std::filesystem::path& path) {
  const std::string source = path.string();
  std::optional<h5::File> file;
  try {
    file.emplace(h5::File::open_read(path));
  } catch (const h5::Failure& e) {
    throw PackageError(fmt::format("{}: {}", source, e.what()));
  }
  ScenePackage pkg = read_from(h5::checked_reader<PackageError>(*file, source));
  validate_package(pkg, source);
  return pkg;
}

// Bytes of private data mappings this process holds (VmData), 0 if unknown.
std::uint64_t data_in_use() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);) {
    if (line.starts_with("VmData:")) return std::strtoull(line.c_str() + 7, nullptr, 10) * 1024;
  }
  return 0;
}

// The child may allocate what reading a package of this size can need (all
// its data, expanded as far as compression is allowed to, twice over) and no
// more: a crafted length field makes libhdf5 allocate and clear gigabytes
// before it notices (a string claiming 4 GB cost 10 s and 8 GB over the two
// reads, docs/fuzzing.md); under the limit that allocation fails at once.
void limit_memory(const std::filesystem::path& path) {
  std::error_code ec;
  const std::uint64_t file_bytes = std::filesystem::file_size(path, ec);
  const std::uint64_t in_use = data_in_use();
  if (ec || in_use == 0) return;
  const std::uint64_t allowed = in_use + 2 * h5::kMaxInflation * file_bytes + (std::uint64_t{256} << 20);
  const rlimit limit{allowed, allowed};
  setrlimit(RLIMIT_DATA, &limit);
}

// The child of probe(): reads the package and writes "ok" or its error line.
[[noreturn]] void probe_child(const std::filesystem::path& path, int out) {
  // A crash here is an answer: the parent names the signal, so the child
  // must die of it (not run a handler inherited from the caller) and
  // leave no core file.
  for (const int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) std::signal(sig, SIG_DFL);
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);
  limit_memory(path);
  std::string answer = "ok";
  try {
    read_in_process(path);
  } catch (const PackageError& e) {
    answer = std::string("error ") + e.what();
  } catch (const std::exception& e) {
    answer = fmt::format("error {}: {} (expected a package)", path.string(), e.what());
  }
  const bool written = ::write(out, answer.data(), answer.size()) == static_cast<ssize_t>(answer.size());
  ::_exit(written ? 0 : 1);  // no atexit handlers, no stdio flush: those belong to the parent
}

// libhdf5 1.10 crashes on some crafted metadata that passes its checksums
// (a division by zero in H5D__chunk_set_info, a wild read in
// H5F__accum_read: docs/fuzzing.md), and the HDF Group does not treat
// hostile files as defects. So a package is first read in a forked child:
// a crash there becomes one PackageError line instead of ending the caller,
// and only a package the child read cleanly is read again in this process.
// If no child can be started, the read goes ahead unprotected.
void probe(const std::filesystem::path& path) {
  int fds[2];
  if (::pipe(fds) != 0) return;
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(fds[0]);
    probe_child(path, fds[1]);
  }
  ::close(fds[1]);
  if (child < 0) {
    ::close(fds[0]);
    return;
  }
  std::string answer;
  char buf[4096];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) != 0;) {
    if (n > 0) answer.append(buf, static_cast<size_t>(n));
    if (n < 0 && errno != EINTR) break;
  }
  ::close(fds[0]);
  int status = 0;
  const bool reaped = ::waitpid(child, &status, 0) == child;
  if (answer == "ok") return;
  if (answer.starts_with("error ")) throw PackageError(answer.substr(6));
  const std::string how = reaped && WIFSIGNALED(status) ? strsignal(WTERMSIG(status)) : "no answer";
  // The crash may in principle be ours, but every one seen was in libhdf5.
  throw PackageError(
      fmt::format("{}: reading it crashed the checking process ({}; expected a well-formed HDF5 file: this "
                  "one is corrupt "
                  "or crafted)",
                  path.string(), how));
}

}  // namespace

ScenePackage read_package(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw PackageError(fmt::format("{}: no such package file", path.string()));
  }
  probe(path);
  return read_in_process(path);
}

void write_package(const ScenePackage& package, const std::filesystem::path& path) {
  validate_package(package, path.string());
  try {
    h5::write_atomically(path, [&package](h5::File& f) { write_to(f, package); });
  } catch (const h5::Failure& e) {
    throw PackageError(fmt::format("{}: cannot write package: {}", path.string(), e.what()));
  }
}

double displacement_error_at_rank(const ScenePackage& package, int rank) {
  const auto& e = package.reduction.rel_error;
  if (rank < 1 || rank > e.size()) return std::nan("");
  return e[rank - 1];
}

}  // namespace phasecast::core
