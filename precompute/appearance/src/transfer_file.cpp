// OBJ input and HDF5 output of the standalone transfer tool (docs/transfer.md).

#include "phasecast/core/package.h"
// OBJ files are read by the one reader of the simulation stage (obj_mesh.h).

#include "phasecast/precompute/appearance/transfer_file.h"

#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/mesh_geometry.h"
#include "phasecast/precompute/simulation/obj_mesh.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace phasecast::precompute {
namespace {

namespace h5 = core::h5;
}  // namespace

TransferMesh load_obj_mesh(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw std::runtime_error(fmt::format("{}: no such mesh file", path.string()));
  const ObjMesh obj = read_obj(path);
  if (obj.triangles.rows() == 0)
    throw std::runtime_error(fmt::format("{}: expected at least one face, found none", path.string()));
  TransferMesh mesh;
  mesh.positions = obj.vertices.cast<float>();
  mesh.triangles = obj.triangles.cast<std::uint32_t>();
  mesh.normals = core::vertex_normals(mesh.positions, mesh.triangles);
  return mesh;
}

TransferMesh make_double_sided(const TransferMesh& mesh) {
  TransferMesh out = mesh;
  std::vector<int> all(static_cast<size_t>(mesh.positions.rows()));
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  core::add_back_side(out.positions, out.normals, out.triangles, all);
  return out;
}

void write_transfer_file(const TransferFile& file, const std::filesystem::path& path) {
  const auto S = static_cast<std::uint64_t>(file.positions.rows());
  if (file.normals.rows() != file.positions.rows() || file.transfer.rows() != file.positions.rows() ||
      file.transfer.cols() != core::kTransferPerPoint) {
    throw std::invalid_argument(fmt::format(
        "{}: transfer file needs S x 3 positions and normals and S x 48 transfer", path.string()));
  }
  try {
    h5::write_atomically(path, [&file, S](h5::File& f) {
      f.write("/positions", file.positions.data(), {S, 3});
      f.write("/normals", file.normals.data(), {S, 3});
      f.write("/transfer", file.transfer.data(), {S, 3, 16});
      f.write_attribute("mode", std::string(transfer_mode_name(file.options.mode)));
      f.write_attribute("rays", static_cast<std::int32_t>(file.options.rays));
      f.write_attribute("bounces", static_cast<std::int32_t>(file.options.bounces));
      f.write_attribute("albedo", std::vector<float>(file.options.albedo.begin(), file.options.albedo.end()));
    });
  } catch (const h5::Failure& e) {
    throw std::runtime_error(fmt::format("{}: cannot write transfer file: {}", path.string(), e.what()));
  }
}

TransferFile read_transfer_file(const std::filesystem::path& path) {
  const std::string source = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw std::runtime_error(fmt::format("{}: no such transfer file", source));
  }
  try {
    const h5::File f = h5::File::open_read(path);
    const h5::Reader r = h5::checked_reader<std::runtime_error>(f, source);
    const auto S = r.require("/positions", h5::Dtype::f32, 2).dims[0];
    r.require_shape("/positions", h5::Dtype::f32, {S, 3});
    r.require_shape("/normals", h5::Dtype::f32, {S, 3});
    r.require_shape("/transfer", h5::Dtype::f32, {S, 3, 16});
    TransferFile out;
    const auto rows = static_cast<Eigen::Index>(S);
    out.positions.resize(rows, 3);
    out.normals.resize(rows, 3);
    out.transfer.resize(rows, core::kTransferPerPoint);
    r.read_into("/positions", out.positions.data(), out.positions.size());
    r.read_into("/normals", out.normals.data(), out.normals.size());
    r.read_into("/transfer", out.transfer.data(), out.transfer.size());
    out.options.mode = parse_transfer_mode(f.read_attribute_string("mode"));
    out.options.rays = static_cast<int>(f.read_attribute_number("rays"));
    out.options.bounces = static_cast<int>(f.read_attribute_number("bounces"));
    const auto albedo = f.read_attribute_floats("albedo");
    if (albedo.size() != 3)
      throw std::runtime_error(fmt::format("{}: attribute albedo: expected 3 floats", source));
    std::copy(albedo.begin(), albedo.end(), out.options.albedo.begin());
    return out;
  } catch (const h5::Failure& e) {
    throw std::runtime_error(fmt::format("{}: {}", source, e.what()));
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(fmt::format("{}: attribute mode: {}", source, e.what()));
  }
}

namespace {

constexpr const char* kTransfersFormat = "phasecast-stage-transfers";
constexpr int kTransfersVersion = 1;

void check_stage_transfers(const StageTransfers& t, const std::filesystem::path& path) {
  const auto T = static_cast<Eigen::Index>(t.nodes.size());
  const auto S = t.rest_positions.rows();
  if (static_cast<Eigen::Index>(t.roles.size()) != T || t.fields.rows() != T || t.q_u.rows() != T ||
      t.fields.cols() != core::kTransferPerPoint * S || t.rest_positions.cols() != 3 ||
      static_cast<Eigen::Index>(t.deformable.size()) != S) {
    throw std::invalid_argument(fmt::format(
        "{}: a transfers file needs one role, field (48S) and q_u row per node and S x 3 rest points; got {} "
        "nodes, {} roles, {} x {} fields, {} q_u rows, {} x {} rest points, {} deformable flags",
        path.string(), T, t.roles.size(), t.fields.rows(), t.fields.cols(), t.q_u.rows(),
        t.rest_positions.rows(), t.rest_positions.cols(), t.deformable.size()));
  }
}

}  // namespace

void write_stage_transfers(const StageTransfers& t, const std::filesystem::path& path) {
  check_stage_transfers(t, path);
  const auto T = static_cast<std::uint64_t>(t.nodes.size());
  const auto S = static_cast<std::uint64_t>(t.rest_positions.rows());
  std::vector<std::uint8_t> roles(t.roles.size());
  std::transform(t.roles.begin(), t.roles.end(), roles.begin(),
                 [](TransferRole r) { return static_cast<std::uint8_t>(r); });
  try {
    h5::write_atomically(path, [&](h5::File& f) {
      f.write("/fields", t.fields.data(), {T, S, 3, 16});
      f.write("/nodes", t.nodes);
      f.write("/roles", roles);
      f.write("/q_u", t.q_u.data(), {T, static_cast<std::uint64_t>(t.q_u.cols())});
      f.write("/cluster_labels", t.labels);
      f.write("/rest_positions", t.rest_positions.data(), {S, 3});
      f.write("/deformable", t.deformable);
      f.write_attribute("format", std::string(kTransfersFormat));
      f.write_attribute("format_version", static_cast<std::int32_t>(kTransfersVersion));
      f.write_attribute("scene", t.scene);
      f.write_attribute("rays", t.rays);
      f.write_attribute("bounces", t.bounces);
    });
  } catch (const h5::Failure& e) {
    throw std::runtime_error(fmt::format("{}: cannot write transfers file: {}", path.string(), e.what()));
  }
}

StageTransfers read_stage_transfers(const std::filesystem::path& path) {
  const std::string source = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw std::runtime_error(fmt::format("{}: no such transfers file", source));
  try {
    const h5::File f = h5::File::open_read(path);
    const h5::Reader r = h5::checked_reader<std::runtime_error>(f, source);
    if (!f.has_attribute("format") || r.text("format") != kTransfersFormat)
      r.fail("/@format", fmt::format("expected {} (a file of --save-transfers)", kTransfersFormat));
    if (r.number("format_version") != kTransfersVersion)
      r.fail("/@format_version", fmt::format("expected {}", kTransfersVersion));
    StageTransfers t;
    t.nodes = r.vector<std::int32_t>("/nodes");
    const auto T = static_cast<std::uint64_t>(t.nodes.size());
    const auto S = r.require("/rest_positions", h5::Dtype::f32, 2).dims[0];
    r.require_shape("/rest_positions", h5::Dtype::f32, {S, 3});
    r.require_shape("/fields", h5::Dtype::f32, {T, S, 3, 16});
    r.require_shape("/roles", h5::Dtype::u8, {T});
    r.require_shape("/deformable", h5::Dtype::u8, {S});
    const auto ru = r.require("/q_u", h5::Dtype::f32, 2).dims[1];
    r.require_shape("/q_u", h5::Dtype::f32, {T, ru});
    t.rest_positions = r.matrix<float>("/rest_positions");
    t.fields.resize(static_cast<Eigen::Index>(T), static_cast<Eigen::Index>(core::kTransferPerPoint * S));
    r.read_into("/fields", t.fields.data(), t.fields.size());
    t.q_u = r.matrix<float>("/q_u");
    for (const std::uint8_t role : r.vector<std::uint8_t>("/roles")) {
      if (role > static_cast<std::uint8_t>(TransferRole::reported))
        r.fail("/roles",
               fmt::format("expected 0 (representative), 1 (picking) or 2 (reported), got {}", role));
      t.roles.push_back(static_cast<TransferRole>(role));
    }
    t.labels = r.vector<std::int32_t>("/cluster_labels");
    t.deformable = r.vector<std::uint8_t>("/deformable");
    t.scene = r.text("scene");
    t.rays = static_cast<std::int32_t>(r.number("rays"));
    t.bounces = static_cast<std::int32_t>(r.number("bounces"));
    return t;
  } catch (const h5::Failure& e) {
    throw std::runtime_error(fmt::format("{}: {}", source, e.what()));
  }
}

}  // namespace phasecast::precompute
