#include "phasecast/precompute/simulation/tet_mesh.h"

#include <fmt/format.h>
#include <tetgen.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::precompute {
namespace {

const char* tetgen_reason(int code) {
  switch (code) {
    case 1:
      return "out of memory";
    case 3:
      return "the surface intersects itself";
    case 4:
      return "a very small feature size";
    case 5:
      return "two very close facets";
    case 10:
      return "invalid input surface (is it closed?)";
    default:
      return "internal TetGen error";
  }
}

// Faces that belong to exactly one tet, oriented away from that tet's fourth vertex.
Eigen::MatrixX3i boundary_faces(const Eigen::MatrixX4i& tets) {
  static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  std::map<std::array<int, 3>, std::pair<int, std::array<int, 3>>> faces;
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    for (const auto& f : kFaces) {
      std::array<int, 3> oriented = {tets(t, f[0]), tets(t, f[1]), tets(t, f[2])};
      std::array<int, 3> key = oriented;
      std::sort(key.begin(), key.end());
      auto& entry = faces[key];
      ++entry.first;
      entry.second = oriented;
    }
  }
  std::vector<std::array<int, 3>> out;
  for (const auto& [key, entry] : faces) {
    if (entry.first == 1) out.push_back(entry.second);
  }
  Eigen::MatrixX3i b(static_cast<Eigen::Index>(out.size()), 3);
  for (size_t i = 0; i < out.size(); ++i)
    b.row(static_cast<Eigen::Index>(i)) << out[i][0], out[i][1], out[i][2];
  return b;
}

}  // namespace

TetMesh tetrahedralize(const ObjMesh& surface, double max_volume, double quality) {
  tetgenio in, out;
  in.firstnumber = 0;
  in.numberofpoints = static_cast<int>(surface.vertices.rows());
  in.pointlist = new REAL[static_cast<size_t>(3 * in.numberofpoints)];
  for (int i = 0; i < in.numberofpoints; ++i)
    for (int k = 0; k < 3; ++k) in.pointlist[3 * i + k] = surface.vertices(i, k);
  in.numberoffacets = static_cast<int>(surface.triangles.rows());
  in.facetlist = new tetgenio::facet[static_cast<size_t>(in.numberoffacets)];
  for (int f = 0; f < in.numberoffacets; ++f) {
    tetgenio::facet& facet = in.facetlist[f];
    facet.numberofpolygons = 1;
    facet.polygonlist = new tetgenio::polygon[1];
    facet.numberofholes = 0;
    facet.holelist = nullptr;
    facet.polygonlist[0].numberofvertices = 3;
    facet.polygonlist[0].vertexlist = new int[3];
    for (int k = 0; k < 3; ++k) facet.polygonlist[0].vertexlist[k] = surface.triangles(f, k);
  }
  std::string switches = fmt::format("pq{}a{}Q", quality, max_volume);
  tetgenbehavior behaviour;
  if (!behaviour.parse_commandline(switches.data())) throw std::runtime_error("TetGen rejected " + switches);
  try {
    tetrahedralize(&behaviour, &in, &out);
  } catch (int code) {
    throw std::runtime_error(fmt::format("TetGen failed: {}", tetgen_reason(code)));
  }
  if (out.numberoftetrahedra == 0)
    throw std::runtime_error("TetGen produced no tetrahedra (is the surface closed?)");
  TetMesh mesh;
  mesh.vertices.resize(out.numberofpoints, 3);
  for (int i = 0; i < out.numberofpoints; ++i)
    for (int k = 0; k < 3; ++k) mesh.vertices(i, k) = out.pointlist[3 * i + k];
  mesh.tets.resize(out.numberoftetrahedra, 4);
  for (int t = 0; t < out.numberoftetrahedra; ++t) {
    for (int k = 0; k < 4; ++k) mesh.tets(t, k) = out.tetrahedronlist[t * out.numberofcorners + k];
    Eigen::Matrix3d D;
    for (int k = 0; k < 3; ++k)
      D.col(k) = (mesh.vertices.row(mesh.tets(t, k + 1)) - mesh.vertices.row(mesh.tets(t, 0))).transpose();
    if (D.determinant() < 0) std::swap(mesh.tets(t, 2), mesh.tets(t, 3));
  }
  mesh.boundary = boundary_faces(mesh.tets);
  return mesh;
}

}  // namespace phasecast::precompute
