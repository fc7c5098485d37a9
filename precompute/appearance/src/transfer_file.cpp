// OBJ input and HDF5 output of the standalone transfer tool (docs/transfer.md).
// The HDF5 layer is phasecast_core's private RAII wrapper (core/src/hdf5_file.h).

#include "phasecast/precompute/appearance/transfer_file.h"

#include "phasecast/core/hdf5_file.h"

#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include <cmath>
#include <stdexcept>

namespace phasecast::precompute {
namespace {

namespace h5 = core::h5;

std::string one_line(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
  for (char& c : s) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return s;
}

void check_dims(const h5::File& f, const std::string& source, const std::string& name,
                const std::vector<std::uint64_t>& want, const char* expected) {
  const auto info = f.info(name);
  if (info.dtype != h5::Dtype::f32 || info.dims.size() != want.size()) {
    throw std::runtime_error(fmt::format("{}: {}: expected float32 {}", source, name, expected));
  }
  for (size_t i = 0; i < want.size(); ++i) {
    if (want[i] != 0 && info.dims[i] != want[i]) {
      throw std::runtime_error(fmt::format("{}: {}: expected float32 {}", source, name, expected));
    }
  }
}

}  // namespace

TransferMesh load_obj_mesh(const std::filesystem::path& path) {
  const std::string source = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw std::runtime_error(fmt::format("{}: no such mesh file", source));
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  config.mtl_search_path = "";  // materials do not matter for transfer geometry
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(source, config)) {
    throw std::runtime_error(
        fmt::format("{}: not a readable OBJ file: {}", source, one_line(reader.Error())));
  }
  const auto& vertices = reader.GetAttrib().vertices;
  TransferMesh mesh;
  const auto S = static_cast<Eigen::Index>(vertices.size() / 3);
  mesh.positions.resize(S, 3);
  for (Eigen::Index i = 0; i < S; ++i) {
    for (int j = 0; j < 3; ++j) {
      const float x = vertices[static_cast<size_t>(3 * i + j)];
      if (!std::isfinite(x))
        throw std::runtime_error(fmt::format("{}: vertex {} is not finite", source, i + 1));
      mesh.positions(i, j) = x;
    }
  }
  std::vector<std::uint32_t> indices;
  for (const auto& shape : reader.GetShapes()) {
    size_t offset = 0;
    for (const auto count : shape.mesh.num_face_vertices) {
      if (count == 3) {
        for (size_t j = 0; j < 3; ++j) {
          const int v = shape.mesh.indices[offset + j].vertex_index;
          if (v < 0 || v >= S) {
            throw std::runtime_error(
                fmt::format("{}: face refers to vertex {}, expected 1..{}", source, v + 1, S));
          }
          indices.push_back(static_cast<std::uint32_t>(v));
        }
      }
      offset += count;
    }
  }
  if (indices.empty())
    throw std::runtime_error(fmt::format("{}: expected at least one face, found none", source));
  mesh.triangles =
      Eigen::Map<const MatrixXuR>(indices.data(), static_cast<Eigen::Index>(indices.size() / 3), 3);
  mesh.normals = vertex_normals(mesh.positions, mesh.triangles);
  return mesh;
}

TransferMesh make_double_sided(const TransferMesh& mesh) {
  const Eigen::Index S = mesh.positions.rows(), F = mesh.triangles.rows();
  TransferMesh out;
  out.positions.resize(2 * S, 3);
  out.positions << mesh.positions, mesh.positions;
  out.normals.resize(2 * S, 3);
  out.normals << mesh.normals, -mesh.normals;
  out.triangles.resize(2 * F, 3);
  out.triangles.topRows(F) = mesh.triangles;
  const auto offset = static_cast<std::uint32_t>(S);
  for (Eigen::Index f = 0; f < F; ++f) {
    // Reversed winding over the copies: the back face looks the other way.
    out.triangles.row(F + f) << mesh.triangles(f, 0) + offset, mesh.triangles(f, 2) + offset,
        mesh.triangles(f, 1) + offset;
  }
  return out;
}

void write_transfer_file(const TransferFile& file, const std::filesystem::path& path) {
  const auto S = static_cast<std::uint64_t>(file.positions.rows());
  if (file.normals.rows() != file.positions.rows() || file.transfer.rows() != file.positions.rows() ||
      file.transfer.cols() != 48) {
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
    for (const char* name : {"/positions", "/normals", "/transfer"}) {
      if (!f.exists(name)) throw std::runtime_error(fmt::format("{}: {}: missing dataset", source, name));
    }
    const auto S = f.info("/positions").dims.empty() ? 0 : f.info("/positions").dims[0];
    check_dims(f, source, "/positions", {0, 3}, "S x 3");
    check_dims(f, source, "/normals", {S, 3}, "S x 3 like /positions");
    check_dims(f, source, "/transfer", {S, 3, 16}, "S x 3 x 16 like /positions");
    TransferFile out;
    const auto rows = static_cast<Eigen::Index>(S);
    out.positions.resize(rows, 3);
    out.normals.resize(rows, 3);
    out.transfer.resize(rows, 48);
    f.read("/positions", out.positions.data());
    f.read("/normals", out.normals.data());
    f.read("/transfer", out.transfer.data());
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
