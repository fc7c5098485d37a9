#pragma once
// The deformable system the simulator integrates: particles with lumped
// masses, the elastic elements acting on them, air-drag triangles, rigid box
// obstacles and pinned particles. Everything is expressed in the frame of the
// rigid support (the paper simulates in the support's frame, §3), so pinned
// particles never move and obstacles are static.

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace phasecast::precompute {

// Lamé parameters (N/m for membranes, Pa for solids).
struct Lame {
  double mu = 0;
  double lambda = 0;
};

// Co-rotational triangle membrane (cloth, leaves): in-plane stretch and shear.
struct MembraneElement {
  std::array<int, 3> v{};
  Eigen::Matrix2d Dm_inv;  // inverse of the rest edge matrix in the triangle's own 2D frame
  double area = 0;         // rest area, m^2
  Lame lame;
};

// Dihedral bending hinge: v[0], v[1] the shared edge, v[2], v[3] the opposite vertices.
struct HingeElement {
  std::array<int, 4> v{};
  double rest_angle = 0;  // signed dihedral angle at rest, rad
  double stiffness = 0;   // N*m: bending modulus * 3|e|^2 / (A1 + A2)
};

// Rod stretch (stems): E = 1/2 (EA / l0) (l - l0)^2.
struct RodStretchElement {
  int a = 0, b = 0;
  double rest_length = 0;
  double stiffness = 0;  // EA / l0, N/m
};

// Rod bending at vertex b between edges (a,b) and (b,c): E = 1/2 k (|t2 - t1| - c0)^2, k = EI / l-bar.
struct RodBendElement {
  int a = 0, b = 0, c = 0;
  double rest_turning = 0;  // c0 = |t2 - t1| at rest
  double stiffness = 0;     // N*m
};

// The energy of a solid's tetrahedra: co-rotational linear (`tet_fem`), or
// Smith, de Goes & Kim 2018's stable neo-Hookean (`tet_neo_hookean`), a
// hyperelastic rubber that stays defined and pushes back through inversion.
enum class TetEnergy { corotational, stable_neo_hookean };

// Tetrahedron of a solid.
struct TetElement {
  std::array<int, 4> v{};
  Eigen::Matrix3d Dm_inv;  // inverse rest edge matrix [x1-x0, x2-x0, x3-x0]
  double volume = 0;       // rest volume, m^3
  Lame lame;               // of linear elasticity, which both energies match at small strain
  TetEnergy energy = TetEnergy::corotational;
};

// Linear air drag on a triangle: f = -c A (n . v_rel) n, shared by its three vertices.
struct DragTriangle {
  std::array<int, 3> v{};
  double coefficient = 0;  // c, kg / (m^2 s)
};

// Axis-aligned rigid box (door board, pot, dashboard) in the support frame.
struct BoxObstacle {
  std::string name;
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
};

struct DeformableModel {
  Eigen::VectorXd rest;              // 3V rest positions, support frame
  Eigen::VectorXd mass;              // V lumped masses, kg
  std::vector<std::uint8_t> pinned;  // V: 1 = attached to the support
  Eigen::MatrixXi surface;           // F x 3 triangles a viewer draws (cloth, leaves, solid boundary)
  std::vector<MembraneElement> membranes;
  std::vector<HingeElement> hinges;
  std::vector<RodStretchElement> rod_stretch;
  std::vector<RodBendElement> rod_bend;
  // Braces: axial springs between two vertices of any bodies, never drawn or
  // exported; with a non-collinear anchor they make a weld's joint stiff.
  std::vector<RodStretchElement> braces;
  std::vector<TetElement> tets;
  std::vector<DragTriangle> drag;
  std::vector<BoxObstacle> obstacles;
  double thickness =
      0.005;  // contact distance kept from obstacles and, with self_collision, between surfaces, m
  bool self_collision = false;  // proximity repulsion between the surface triangles and vertices
  double self_friction = 0;     // Coulomb's coefficient between surfaces in self-contact
  // CCD's later detections of a step test only pairs with a moved vertex; false:
  // every detection is whole (the same result, slower: the reference to measure against).
  bool incremental_ccd = true;

  int vertices() const { return static_cast<int>(mass.size()); }
};

// Builders: compute the rest quantities of one element from the rest positions
// in `model.rest`. They throw std::invalid_argument naming the element when it
// is degenerate (zero area/length) or inverted (negative tet volume).
void add_membrane(DeformableModel& model, std::array<int, 3> v, Lame lame);
void add_hinge(DeformableModel& model, std::array<int, 4> v, double bending_modulus);
void add_rod_stretch(DeformableModel& model, int a, int b, double ea);
void add_rod_bend(DeformableModel& model, int a, int b, int c, double ei);
// A brace between vertices a and b: energy EA / (2 l0) (l - l0)^2, as a rod edge's.
void add_brace(DeformableModel& model, int a, int b, double ea);
void add_tet(DeformableModel& model, std::array<int, 4> v, Lame lame,
             TetEnergy energy = TetEnergy::corotational);

// Lamé parameters of an isotropic material from Young's modulus and Poisson's ratio.
Lame lame_from_young(double young, double poisson);

// Every interior edge of a triangle mesh as a hinge (v0, v1 shared; v2, v3 opposite).
std::vector<std::array<int, 4>> mesh_hinges(const Eigen::MatrixXi& triangles);

}  // namespace phasecast::precompute
