// OBJ input and HDF5 output of the standalone transfer tool (docs/transfer.md).

#include "phasecast/core/package.h"
// OBJ files are read by the one reader of the simulation stage (obj_mesh.h).

#include "phasecast/precompute/appearance/transfer_file.h"

#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/mesh_geometry.h"
#include "phasecast/precompute/simulation/obj_mesh.h"

#include <fmt/format.h>

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

}  // namespace phasecast::precompute
