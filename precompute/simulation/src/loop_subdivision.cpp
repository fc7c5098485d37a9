#include "phasecast/precompute/simulation/embedding.h"

#include <fmt/format.h>

#include <cmath>
#include <map>
#include <stdexcept>
#include <utility>
#include <vector>

namespace phasecast::precompute {
namespace {

using Edge = std::pair<int, int>;  // (a, b), a < b
using Triplets = std::vector<Eigen::Triplet<double>>;

Edge edge(int a, int b) {
  return {std::min(a, b), std::max(a, b)};
}

// Loop's vertex weight of each of k neighbours of an interior vertex.
double loop_beta(size_t k) {
  constexpr double kPi = 3.14159265358979323846;
  const double c = 3.0 / 8 + std::cos(2 * kPi / static_cast<double>(k)) / 4;
  return (5.0 / 8 - c * c) / static_cast<double>(k);
}

// Each edge with the vertices opposite it (one on a boundary edge, two inside).
std::map<Edge, std::vector<int>> edge_opposites(const Eigen::MatrixXi& T) {
  std::map<Edge, std::vector<int>> out;  // sorted: edge points are numbered in this order
  for (Eigen::Index t = 0; t < T.rows(); ++t)
    for (int k = 0; k < 3; ++k) out[edge(T(t, k), T(t, (k + 1) % 3))].push_back(T(t, (k + 2) % 3));
  return out;
}

// The even (old) points: each vertex from itself and its neighbours.
void vertex_points(const std::map<Edge, std::vector<int>>& edges, int n, Triplets& w) {
  std::vector<std::vector<int>> neighbours(static_cast<size_t>(n)), boundary(static_cast<size_t>(n));
  for (const auto& [e, opposite] : edges) {
    neighbours[static_cast<size_t>(e.first)].push_back(e.second);
    neighbours[static_cast<size_t>(e.second)].push_back(e.first);
    if (opposite.size() == 1) {
      boundary[static_cast<size_t>(e.first)].push_back(e.second);
      boundary[static_cast<size_t>(e.second)].push_back(e.first);
    }
  }
  for (int v = 0; v < n; ++v) {
    const auto& ring = neighbours[static_cast<size_t>(v)];
    const auto& rim = boundary[static_cast<size_t>(v)];
    if (ring.empty() || rim.size() > 2) {
      w.emplace_back(v, v, 1.0);  // in no triangle, or where two fans touch: no smooth rule applies
    } else if (rim.size() == 2) {
      w.emplace_back(v, v, 3.0 / 4);
      for (int u : rim) w.emplace_back(v, u, 1.0 / 8);
    } else {
      const double beta = loop_beta(ring.size());
      w.emplace_back(v, v, 1 - static_cast<double>(ring.size()) * beta);
      for (int u : ring) w.emplace_back(v, u, beta);
    }
  }
}

// One level: weights of the refined points over the n old ones, and the refined triangles.
Subdivision subdivide_once(const Eigen::MatrixXi& T, int n) {
  const auto edges = edge_opposites(T);
  Triplets w;
  vertex_points(edges, n, w);
  std::map<Edge, int> edge_point;
  int next = n;
  for (const auto& [e, opposite] : edges) {
    edge_point[e] = next;
    if (opposite.size() == 2) {
      w.emplace_back(next, e.first, 3.0 / 8);
      w.emplace_back(next, e.second, 3.0 / 8);
      for (int o : opposite) w.emplace_back(next, o, 1.0 / 8);
    } else {
      w.emplace_back(next, e.first, 1.0 / 2);  // a boundary (or non-manifold) edge stays a straight line
      w.emplace_back(next, e.second, 1.0 / 2);
    }
    ++next;
  }
  Subdivision s;
  s.weights.resize(next, n);
  s.weights.setFromTriplets(w.begin(), w.end());
  s.triangles.resize(4 * T.rows(), 3);
  for (Eigen::Index t = 0; t < T.rows(); ++t) {
    const int a = T(t, 0), b = T(t, 1), c = T(t, 2);
    const int ab = edge_point[edge(a, b)], bc = edge_point[edge(b, c)], ca = edge_point[edge(c, a)];
    s.triangles.row(4 * t) << a, ab, ca;
    s.triangles.row(4 * t + 1) << ab, b, bc;
    s.triangles.row(4 * t + 2) << ca, bc, c;
    s.triangles.row(4 * t + 3) << ab, bc, ca;
  }
  return s;
}

}  // namespace

Subdivision loop_subdivision(const Eigen::MatrixXi& triangles, int vertices, int levels) {
  if (levels < 0 || (triangles.size() && (triangles.minCoeff() < 0 || triangles.maxCoeff() >= vertices))) {
    throw std::invalid_argument(fmt::format(
        "loop_subdivision: expected levels >= 0 and triangle corners in 0..{}, got {} levels, corners {}..{}",
        vertices - 1, levels, triangles.size() ? triangles.minCoeff() : 0,
        triangles.size() ? triangles.maxCoeff() : 0));
  }
  Subdivision out;
  out.weights.resize(vertices, vertices);
  out.weights.setIdentity();
  out.triangles = triangles;
  for (int level = 0; level < levels; ++level) {
    Subdivision step = subdivide_once(out.triangles, static_cast<int>(out.weights.rows()));
    out.weights = VertexEmbedding(step.weights * out.weights);
    out.triangles = std::move(step.triangles);
  }
  return out;
}

}  // namespace phasecast::precompute
