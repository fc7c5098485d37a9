// GPU evaluation on OSMesa (llvmpipe): transform-feedback positions equal
// x_bar + U_u q_u (eq. 7) computed on the CPU, and a transfer-lit sphere
// matches the closed-form irradiance of Ramamoorthi & Hanrahan (2001).

#include "phasecast/client/frame_sources.h"
#include "phasecast/client/image_io.h"
#include "phasecast/client/low_rank_renderer.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <cmath>
#include <cstdlib>
#include <numbers>
#include <optional>
#include <random>
#include <string_view>

namespace phasecast::client {
namespace {

constexpr double kPi = std::numbers::pi;

// ||gpu - cpu|| <= 1e-5 ||cpu|| per point (plus a float-epsilon floor for
// points at the origin).
void expect_positions_match(const VertexDump& gpu, const std::vector<double>& cpu) {
  ASSERT_EQ(gpu.positions.size(), cpu.size());
  double worst = 0;
  for (std::size_t v = 0; v < cpu.size() / 3; ++v) {
    const Eigen::Vector3d c(cpu[3 * v], cpu[3 * v + 1], cpu[3 * v + 2]);
    const Eigen::Vector3d g(gpu.positions[3 * v], gpu.positions[3 * v + 1], gpu.positions[3 * v + 2]);
    const double rel = (g - c).norm() / (c.norm() + 1e-6);
    worst = std::max(worst, rel);
    ASSERT_LE((g - c).norm(), 1e-5 * c.norm() + 1e-7) << "point " << v;
  }
  ::testing::Test::RecordProperty("worst_relative_error", std::to_string(worst));
}

TEST(GlEvaluation, TransformFeedbackPositionsEqualCpuLowRankSum) {
  const auto package = testing::make_plate_package();
  const auto basis = basis_from_package(package, 1);
  auto backend = make_render_backend("osmesa", 64, 64);
  LowRankRenderer renderer(*backend, basis, 64, 64);
  for (int irf : {0, 3, 5}) {
    for (const auto& f : portrait_frames(package, irf)) {
      if (f.frame % 15 != 4) continue;
      expect_positions_match(renderer.evaluate(f), cpu_positions(basis, f.q_u, f.support));
    }
  }
}

// Ranks well above the 64 floats of per-vertex attributes the paper had.
TEST(GlEvaluation, HighRanksAreEvaluatedExactly) {
  ClientBasis b;
  b.scene = "random";
  const int S = 500, r_u = 80, r_a = 24;
  b.points = S;
  b.rank_u = r_u;
  b.rank_a = r_a;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  auto fill = [&](std::size_t n, float scale) {
    std::vector<float> v(n);
    for (auto& x : v) x = scale * u(rng);
    return v;
  };
  b.mean_shape = fill(3 * S, 2);
  b.normals = fill(3 * S, 1);
  b.U_u = fill(static_cast<std::size_t>(3 * S * r_u), 0.05f);
  b.mean_transfer = fill(48 * S, 0.1f);
  b.U_a = fill(static_cast<std::size_t>(48 * S * r_a), 0.01f);
  for (int v = 0; v < S; ++v) {
    b.deformable.push_back(v % 7 != 0);
    b.attached.push_back(v % 3 != 0);
  }
  for (int t = 0; t + 2 < S; t += 3) {
    for (int k = 0; k < 3; ++k) b.triangles.push_back(static_cast<std::uint32_t>(t + k));
  }
  auto backend = make_render_backend("osmesa", 32, 32);
  LowRankRenderer renderer(*backend, b, 32, 32);
  FrameState f;
  f.frame = 9;
  f.q_u = fill(r_u, 1);
  f.q_a = fill(r_a, 1);
  const Eigen::Matrix3f R =
      Eigen::AngleAxisf(0.8f, Eigen::Vector3f(0.3f, 1, 0.1f).normalized()).toRotationMatrix();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) f.support.push_back(R(i, j));
    f.support.push_back(0.5f * static_cast<float>(i) - 0.2f);
  }
  const VertexDump dump = renderer.evaluate(f);
  expect_positions_match(dump, cpu_positions(b, f.q_u, f.support));

  // Radiance: (M_bar + U_a q_a) . L with the light in the right frame.
  const ShLight light = light_probe("grace");
  const ShLight local = light_in_support_frame(light, R.cast<double>());
  for (int v = 0; v < S; v += 37) {
    std::array<float, 48> t{};
    for (int i = 0; i < 48; ++i) {
      double m = b.mean_transfer[static_cast<std::size_t>(48 * v + i)];
      for (int j = 0; j < r_a; ++j)
        m += double(b.U_a[static_cast<std::size_t>((48 * v + i) * r_a + j)]) *
             f.q_a[static_cast<std::size_t>(j)];
      t[static_cast<std::size_t>(i)] = static_cast<float>(m);
    }
    const auto expected = shade(t.data(), b.attached[static_cast<std::size_t>(v)] ? local : light);
    for (std::size_t c = 0; c < 3; ++c) {
      EXPECT_NEAR(dump.radiance[3 * static_cast<std::size_t>(v) + c], expected[c], 2e-5) << "point " << v;
    }
  }
}

// Closed-form irradiance (Ramamoorthi & Hanrahan 2001, eq. 13) from their
// coefficients and constants, independent of our SH tables.
std::array<double, 3> grace_irradiance(const Eigen::Vector3d& n) {
  const double L[9][3] = {
      {.78908, .43710, .54161},    {.39499, .34989, .60488},    {-.33974, -.18236, -.26940},
      {-.29213, -.05562, .00944},  {-.11141, -.05090, -.12231}, {-.26240, -.22401, -.47479},
      {-.15570, -.09471, -.14733}, {.56014, .21444, .13915},    {.21205, -.05432, -.30374}};
  const double c1 = 0.429043, c2 = 0.511664, c3 = 0.743125, c4 = 0.886227, c5 = 0.247708;
  const double x = n.x(), y = n.y(), z = n.z();
  std::array<double, 3> E{};
  for (int c = 0; c < 3; ++c) {
    // Order: L00, L1-1, L10, L11, L2-2, L2-1, L20, L21, L22.
    E[static_cast<std::size_t>(c)] = c1 * L[8][c] * (x * x - y * y) + c3 * L[6][c] * z * z + c4 * L[0][c] -
                                     c5 * L[6][c] +
                                     2 * c1 * (L[4][c] * x * y + L[7][c] * x * z + L[5][c] * y * z) +
                                     2 * c2 * (L[3][c] * x + L[1][c] * y + L[2][c] * z);
  }
  return E;
}

// A UV sphere whose transfer is the unshadowed diffuse transfer
// (rho/pi) A_l Y_k(n) (spherical-harmonics.md), split between M_bar and U_a.
ClientBasis transfer_sphere(int rings, int segments, const std::array<double, 3>& albedo) {
  ClientBasis b;
  b.scene = "sphere";
  b.rank_u = 1;
  b.rank_a = 1;
  for (int i = 0; i <= rings; ++i) {
    const double theta = kPi * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2 * kPi * j / segments;
      const Eigen::Vector3d n(std::sin(theta) * std::cos(phi), std::cos(theta),
                              std::sin(theta) * std::sin(phi));
      for (int k = 0; k < 3; ++k) {
        b.mean_shape.push_back(static_cast<float>(n[k]));
        b.normals.push_back(static_cast<float>(n[k]));
      }
      const auto y = core::sh_basis(n.x(), n.y(), n.z());
      for (std::size_t c = 0; c < 3; ++c) {
        for (std::size_t k = 0; k < 16; ++k) {
          const double T =
              albedo[c] / kPi * core::clamped_cosine_band(core::sh_band(static_cast<int>(k))) * y[k];
          b.mean_transfer.push_back(static_cast<float>(0.25 * T));
          b.U_a.push_back(static_cast<float>(0.75 * T));  // q_a = 1 adds the rest
        }
      }
    }
  }
  b.points = static_cast<int>(b.mean_shape.size() / 3);
  b.U_u.assign(3 * static_cast<std::size_t>(b.points), 0.0f);
  b.deformable.assign(static_cast<std::size_t>(b.points), 0);
  b.attached.assign(static_cast<std::size_t>(b.points), 1);
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const auto a = static_cast<std::uint32_t>(i * segments + j);
      const auto bb = static_cast<std::uint32_t>(i * segments + (j + 1) % segments);
      const auto c = a + static_cast<std::uint32_t>(segments), d = bb + static_cast<std::uint32_t>(segments);
      // Counter-clockwise seen from outside, as package triangles are (the renderer culls back faces).
      b.triangles.insert(b.triangles.end(), {a, bb, c, bb, d, c});
    }
  }
  return b;
}

TEST(GlEvaluation, TransferLitSphereMatchesClosedFormIrradiance) {
  const std::array<double, 3> albedo{0.8, 0.6, 0.4};
  const ClientBasis sphere = transfer_sphere(24, 48, albedo);
  auto backend = make_render_backend("osmesa", 64, 64);
  LowRankRenderer renderer(*backend, sphere, 64, 64);
  renderer.set_light(light_probe("grace"));
  // Rotating the support rotates the sphere's normals; the light is rotated
  // into the support frame so the world irradiance stays E(R n).
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(1.2, Eigen::Vector3d(0.2, 0.7, -0.4).normalized()).toRotationMatrix();
  for (const Eigen::Matrix3d& rotation : {Eigen::Matrix3d::Identity().eval(), R}) {
    FrameState f;
    f.q_u = {0};
    f.q_a = {1};
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) f.support.push_back(static_cast<float>(rotation(i, j)));
      f.support.push_back(0);
    }
    const VertexDump dump = renderer.evaluate(f);
    for (int v = 0; v < sphere.points; ++v) {
      const auto i = static_cast<std::size_t>(v);
      const Eigen::Vector3d n = rotation * Eigen::Vector3d(sphere.normals[3 * i], sphere.normals[3 * i + 1],
                                                           sphere.normals[3 * i + 2]);
      const auto E = grace_irradiance(n);
      for (std::size_t c = 0; c < 3; ++c) {
        // R-H constants have 6 digits: agreement to 1e-5 absolute.
        ASSERT_NEAR(dump.radiance[3 * i + c], albedo[c] / kPi * E[c], 1e-5)
            << "point " << v << " channel " << c;
      }
    }
  }
}

TEST(GlEvaluation, SphereImageCentreShowsTheIrradianceFacingTheCamera) {
  const std::array<double, 3> albedo{0.8, 0.6, 0.4};
  const ClientBasis sphere = transfer_sphere(48, 96, albedo);
  auto backend = make_render_backend("osmesa", 65, 65);
  LowRankRenderer renderer(*backend, sphere, 65, 65);
  renderer.set_light(light_probe("grace"));
  Camera camera;
  camera.eye = {0, 0, 4};
  camera.target = {0, 0, 0};
  camera.fov_y_deg = 35;
  renderer.set_camera(camera);
  renderer.set_exposure(3);
  FrameState f;
  f.q_u = {0};
  f.q_a = {1};
  const Image image = renderer.render(f);
  const auto E = grace_irradiance(Eigen::Vector3d(0, 0, 1));
  auto srgb = [](double l) {
    l = std::clamp(l, 0.0, 1.0);
    return l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1 / 2.4) - 0.055;
  };
  const std::size_t centre = 4 * (32 * 65 + 32);
  for (std::size_t c = 0; c < 3; ++c) {
    const double expected = 255 * srgb(3 * albedo[c] / kPi * E[c]);
    EXPECT_LE(std::abs(image.rgba[centre + c] - expected), 2.0) << "channel " << c;
  }
  // The background is the clear colour (a display value, not encoded).
  EXPECT_EQ(image.rgba[0], std::lround(255 * 0.02));
}

// The backdrop's floor is lit like an unshadowed diffuse surface facing up:
// (rho / pi) E(up), E from the closed form of Ramamoorthi & Hanrahan.
TEST(GlEvaluation, DiffuseRadianceEqualsClosedFormIrradiance) {
  const std::array<double, 3> albedo{0.3, 0.5, 0.7};
  for (const Eigen::Vector3d& n : {Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0.6, 0, 0.8)}) {
    const auto got = diffuse_radiance(light_probe("grace"), n, albedo);
    const auto E = grace_irradiance(n);
    for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(got[c], albedo[c] / kPi * E[c], 1e-5) << c;
  }
  // Under the white furnace (radiance 1 everywhere) a diffuse surface reflects its albedo.
  const auto white = diffuse_radiance(light_probe("white"), Eigen::Vector3d(0, 0, 1), albedo);
  for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(white[c], albedo[c], 1e-6) << c;
}

// The backdrop (phasecast-render --backdrop on): a floor at the lowest rest
// point, lit by the light's irradiance for an up-facing normal, drawn behind
// the scene; the scene's pixels and its evaluation stay exactly as they are.
TEST(GlEvaluation, BackdropDrawsAGroundBelowTheSceneAndLeavesTheSceneAlone) {
  const std::array<double, 3> albedo{0.8, 0.6, 0.4};
  const ClientBasis sphere = transfer_sphere(24, 48, albedo);  // rest bounds [-1, 1]^3: ground y = -1
  auto backend = make_render_backend("osmesa", 65, 65);
  LowRankRenderer renderer(*backend, sphere, 65, 65);
  renderer.set_light(light_probe("grace"));
  Camera camera;
  camera.eye = {0, 0, 4};
  camera.target = {0, 0, 0};
  camera.fov_y_deg = 35;
  renderer.set_camera(camera);
  FrameState f;
  f.q_u = {0};
  f.q_a = {1};
  const Image plain = renderer.render(f);
  const VertexDump plain_dump = renderer.evaluate(f);
  renderer.set_backdrop(Backdrop::ground);
  const Image framed = renderer.render(f);
  const VertexDump framed_dump = renderer.evaluate(f);
  EXPECT_EQ(framed_dump.positions, plain_dump.positions);
  EXPECT_EQ(framed_dump.radiance, plain_dump.radiance);

  auto pixel = [](const Image& image, int x, int y) {
    const auto i = static_cast<std::size_t>(4 * (y * image.width + x));
    return std::array<int, 3>{image.rgba[i], image.rgba[i + 1], image.rgba[i + 2]};
  };
  auto display = [](const std::array<float, 3>& colour) {
    return std::array<int, 3>{static_cast<int>(std::lround(255 * colour[0])),
                              static_cast<int>(std::lround(255 * colour[1])),
                              static_cast<int>(std::lround(255 * colour[2]))};
  };
  const auto plain_background = display(kPlainBackground), background = display(kBackdropBackground);
  int scene = 0, ground = 0;
  for (int y = 0; y < 65; ++y) {
    for (int x = 0; x < 65; ++x) {
      if (pixel(plain, x, y) != plain_background) {
        ++scene;  // the sphere: the same pixel with the backdrop
        ASSERT_EQ(pixel(framed, x, y), pixel(plain, x, y)) << x << ", " << y;
      } else if (y < 32) {
        ASSERT_EQ(pixel(framed, x, y), background) << x << ", " << y << ": above the horizon";
      } else if (pixel(framed, x, y) != background) {
        ++ground;
      }
    }
  }
  EXPECT_GT(scene, 65 * 65 / 5);
  EXPECT_GT(ground, 65 * 8) << "the floor should fill the lower part of the picture around the sphere";

  // The bottom row's middle sees the floor 0.83 in front of the sphere's
  // centre (fade exp(-0.16 (0.83 / sqrt 3)^2) = 0.96): the floor's radiance
  // (rho / pi) E(up) darkened by the checker by at most 12 %, encoded, mixed
  // with the background.
  const auto E = grace_irradiance(Eigen::Vector3d(0, 1, 0));
  auto srgb = [](double l) {
    l = std::clamp(l, 0.0, 1.0);
    return l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1 / 2.4) - 0.055;
  };
  const auto bottom = pixel(framed, 32, 64);
  for (std::size_t c = 0; c < 3; ++c) {
    const double floor = kGroundAlbedo[c] / kPi * E[c], bg = kBackdropBackground[c];
    const double lo = 255 * (0.94 * srgb(0.88 * floor) + 0.06 * bg),
                 hi = 255 * (0.98 * srgb(floor) + 0.02 * bg);
    EXPECT_GE(bottom[c], lo - 1) << "channel " << c;
    EXPECT_LE(bottom[c], hi + 1) << "channel " << c;
  }

  // Seen from below the ground there is no floor: only the background around the sphere.
  camera.eye = {0, -3, 4};
  renderer.set_camera(camera);
  const Image below = renderer.render(f);
  renderer.set_backdrop(Backdrop::none);
  const Image below_plain = renderer.render(f);
  for (int y = 0; y < 65; ++y) {
    for (int x = 0; x < 65; ++x) {
      if (pixel(below_plain, x, y) == plain_background) {
        ASSERT_EQ(pixel(below, x, y), background) << x << ", " << y;
      }
    }
  }
}

TEST(GlEvaluation, TransferIsDottedWithTheLightOnlyWhenTheLightItSeesChanges) {
  const auto package = testing::make_plate_package();
  auto backend = make_render_backend("osmesa", 32, 32);
  LowRankRenderer renderer(*backend, basis_from_package(package, 1), 32, 32);
  FrameState f = portrait_frames(package, 0)[0];
  renderer.draw(f);
  EXPECT_EQ(renderer.light_dot_passes(), 1u);
  f.q_u[0] += 0.1f;  // deformation and q_a changes alone do not re-dot
  f.q_a[0] += 0.1f;
  renderer.draw(f);
  renderer.evaluate(f);
  EXPECT_EQ(renderer.light_dot_passes(), 1u);
  f.support = portrait_frames(package, 0)[40].support;  // the door turned
  const VertexDump turned = renderer.evaluate(f);
  EXPECT_EQ(renderer.light_dot_passes(), 2u);
  renderer.set_light(light_probe("sky"));
  const VertexDump sky = renderer.evaluate(f);
  EXPECT_EQ(renderer.light_dot_passes(), 3u);
  EXPECT_NE(turned.radiance, sky.radiance);
}

// Four instances on the default grid, one instanced draw: each is its own
// frame evaluated where it stands (the single-instance evaluation moved by
// its placement), and changing one instance's frame changes only its part
// of the picture.
TEST(GlEvaluation, InstancesAreDrawnEachWithItsOwnStateWhereItStands) {
  const auto package = testing::make_plate_package();
  const auto basis = basis_from_package(package, 1);
  const int size = 160;
  auto backend = make_render_backend("osmesa", size, size);
  LowRankRenderer single(*backend, basis, size, size);
  LowRankRenderer renderer(*backend, basis, size, size);
  const auto placements = grid_placements(rest_bounds(basis), 4);
  renderer.set_placements(placements);
  const Camera camera = group_camera(scene_camera(basis), rest_bounds(basis), placements);
  renderer.set_camera(camera);
  const FrameState rest = portrait_frames(package, 0)[0];
  std::vector<FrameState> frames(4, rest);
  frames[2] = portrait_frames(package, 0)[40];  // the door of instance 2 turned, its plate moving
  frames[3] = portrait_frames(package, 3)[20];

  const VertexDump all = renderer.evaluate(frames);
  const std::size_t S = static_cast<std::size_t>(basis.points);
  ASSERT_EQ(all.positions.size(), 4 * 3 * S);
  for (std::size_t i = 0; i < 4; ++i) {
    const VertexDump one = single.evaluate(frames[i]);
    for (std::size_t k = 0; k < 3 * S; ++k) {
      const float moved = one.positions[k] + placements[i](static_cast<int>(k % 3), 3);
      ASSERT_NEAR(all.positions[3 * S * i + k], moved, 1e-5f) << "instance " << i << ", value " << k;
      ASSERT_NEAR(all.radiance[3 * S * i + k], one.radiance[k], 1e-6f) << "instance " << i << ", value " << k;
    }
  }

  // Where instance 2 can appear: its points at rest and moved, projected.
  const Eigen::Matrix4f vp = view_projection(camera, size, size, 2 * scene_radius(basis) + 4);
  Eigen::AlignedBox2f region;
  for (const FrameState* f : {&rest, static_cast<const FrameState*>(&frames[2])}) {
    std::vector<FrameState> just_2(4, rest);
    just_2[2] = *f;
    const VertexDump d = renderer.evaluate(just_2);
    for (std::size_t v = 2 * S; v < 3 * S; ++v) {
      const Eigen::Vector4f clip =
          vp * Eigen::Vector4f(d.positions[3 * v], d.positions[3 * v + 1], d.positions[3 * v + 2], 1);
      region.extend(
          Eigen::Vector2f((clip.x() / clip.w() + 1) * size / 2, (1 - clip.y() / clip.w()) * size / 2));
    }
  }
  std::vector<FrameState> before(4, rest), after(4, rest);
  after[2] = frames[2];
  const Image a = renderer.render(before), b = renderer.render(after);
  int inside = 0, outside = 0;
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const auto at = static_cast<std::size_t>(4 * (y * size + x));
      if (std::equal(&a.rgba[at], &a.rgba[at + 3], &b.rgba[at])) continue;
      const bool in = region.exteriorDistance(Eigen::Vector2f(x + 0.5f, y + 0.5f)) <= 2;
      (in ? inside : outside)++;
    }
  }
  EXPECT_GT(inside, 50) << "instance 2's motion shows";
  EXPECT_EQ(outside, 0) << "no other instance changed";
  EXPECT_THROW(renderer.render(std::span(&rest, 1)), RenderError) << "one frame per placed instance";
}

// Instances that see the same light read one light-dotted copy: it is
// dotted once, a copy that holds a light is kept for whoever sees it next,
// and each instance still shines as it does alone, on every evaluation path
// and with the bases bound in blocks of points (where copy and instance
// numbers part: instance 1 reads copy 0 below).
TEST(GlEvaluation, InstancesThatSeeTheSameLightShareOneLightDot) {
  const auto package = testing::make_plate_package();
  const auto basis = basis_from_package(package, 1);
  auto backend = make_render_backend("osmesa", 64, 64);
  LowRankRenderer single(*backend, basis, 64, 64);
  const FrameState rest = portrait_frames(package, 0)[0], turned = portrait_frames(package, 0)[40];
  ASSERT_NE(rest.support, turned.support);
  const std::size_t values = 3 * static_cast<std::size_t>(basis.points);
  const std::size_t u_a_row = 48 * 4 * static_cast<std::size_t>((basis.rank_a + 3) / 4) * sizeof(float);
  std::optional<Image> per_point_image;
  for (const char* config : {"compute_pass", "per_point_pass", "in_draw", "blocks"}) {
    SCOPED_TRACE(config);
    const bool blocks = std::string_view(config) == "blocks";
    if (blocks) ::setenv("PHASECAST_MAX_STORAGE_BLOCK_BYTES", std::to_string(64 * u_a_row).c_str(), 1);
    LowRankRenderer renderer(*backend, basis, 64, 64);
    ::unsetenv("PHASECAST_MAX_STORAGE_BLOCK_BYTES");
    ASSERT_EQ(renderer.point_blocks(), blocks ? 2 : 1);
    if (std::string_view(config) == "per_point_pass") renderer.set_evaluation(Evaluation::per_point_pass);
    if (std::string_view(config) == "in_draw") renderer.set_evaluation(Evaluation::in_draw);
    renderer.set_placements(grid_placements(rest_bounds(basis), 4));
    std::vector<FrameState> frames(4, rest);
    renderer.draw(frames);
    EXPECT_EQ(renderer.light_dot_passes(), 1u) << "four instances, one light";
    frames[2] = turned;
    renderer.draw(frames);
    EXPECT_EQ(renderer.light_dot_passes(), 2u) << "instance 2's door turned";
    frames.assign(4, turned);
    const VertexDump all_turned = renderer.evaluate(frames);
    EXPECT_EQ(renderer.light_dot_passes(), 2u) << "the turned light's copy is kept";
    frames[0] = rest;
    frames[1] = rest;
    const VertexDump mixed = renderer.evaluate(frames);
    EXPECT_EQ(renderer.light_dot_passes(), 2u) << "and so is the rest light's";
    struct Seen {
      const VertexDump* dump;
      std::size_t instance;
      const FrameState* frame;
    };
    for (const Seen& c : {Seen{&all_turned, 3, &turned}, Seen{&mixed, 0, &rest}, Seen{&mixed, 1, &rest},
                          Seen{&mixed, 2, &turned}}) {
      const VertexDump one = single.evaluate(*c.frame);
      for (std::size_t k = 0; k < values; ++k)
        ASSERT_NEAR(c.dump->radiance[values * c.instance + k], one.radiance[k], 1e-6f)
            << "instance " << c.instance << ", value " << k;
    }
    // The triangle draw's own evaluation reads the copies as the per-point pass does.
    if (std::string_view(config) == "per_point_pass") per_point_image = renderer.render(frames);
    if (std::string_view(config) == "in_draw") {
      ASSERT_TRUE(per_point_image);
      EXPECT_EQ(max_channel_difference(renderer.render(frames), *per_point_image), 0);
    }
  }
}

// Bases larger than one shader storage block are bound a block of points
// at a time: with the block capped at 64 points of U_a (the fixture has 85
// points), two blocks draw the same pixels and evaluate the same values as one.
TEST(GlEvaluation, BasesLargerThanOneStorageBlockAreDrawnInBlocks) {
  const auto package = testing::make_plate_package();
  const auto basis = basis_from_package(package, 1);
  auto backend = make_render_backend("osmesa", 96, 96);
  LowRankRenderer whole(*backend, basis, 96, 96);
  const std::size_t u_a_row = 48 * 4 * static_cast<std::size_t>((basis.rank_a + 3) / 4) * sizeof(float);
  ::setenv("PHASECAST_MAX_STORAGE_BLOCK_BYTES", std::to_string(64 * u_a_row).c_str(), 1);
  LowRankRenderer blocks(*backend, basis, 96, 96);
  ::unsetenv("PHASECAST_MAX_STORAGE_BLOCK_BYTES");
  EXPECT_EQ(whole.point_blocks(), 1);
  ASSERT_EQ(blocks.point_blocks(), 2);
  for (auto* r : {&whole, &blocks}) {
    r->set_placements(grid_placements(rest_bounds(basis), 3));
    r->set_camera(
        group_camera(scene_camera(basis), rest_bounds(basis), grid_placements(rest_bounds(basis), 3)));
  }
  const std::vector<FrameState> frames{portrait_frames(package, 0)[40], portrait_frames(package, 3)[20],
                                       portrait_frames(package, 4)[10]};
  const VertexDump a = whole.evaluate(frames), b = blocks.evaluate(frames);
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.radiance, b.radiance);
  EXPECT_EQ(max_channel_difference(whole.render(frames), blocks.render(frames)), 0);
  blocks.set_evaluation(Evaluation::in_draw);  // a triangle may join two blocks: stays per point
  EXPECT_EQ(max_channel_difference(whole.render(frames), blocks.render(frames)), 0);
}

// Point rows (llvmpipe's default) and point tiles (the GPUs') hold the same
// values and sum them in the same order: the same bits in one block and in
// blocks of points, in every evaluation path, with 32- and 16-bit bases.
TEST(GlEvaluation, BothBasisLayoutsGiveTheSameBits) {
  const auto package = testing::make_plate_package();
  const auto basis = basis_from_package(package, 1);
  auto backend = make_render_backend("osmesa", 96, 96);
  const std::vector<FrameState> frames{portrait_frames(package, 0)[40], portrait_frames(package, 3)[20]};
  for (const char* block_bytes : {"", "blocks"}) {
    for (auto precision : {BasisPrecision::float32, BasisPrecision::float16}) {
      const std::size_t scalar = precision == BasisPrecision::float16 ? 2 : 4;  // bytes per basis value
      const std::size_t u_a_row = 48 * 4 * static_cast<std::size_t>((basis.rank_a + 3) / 4) * scalar;
      if (*block_bytes)
        ::setenv("PHASECAST_MAX_STORAGE_BLOCK_BYTES", std::to_string(64 * u_a_row).c_str(), 1);
      LowRankRenderer rows(*backend, basis, 96, 96, precision, BasisLayout::point_rows);
      LowRankRenderer tiles(*backend, basis, 96, 96, precision, BasisLayout::point_tiles);
      EXPECT_EQ(rows.basis_layout(), BasisLayout::point_rows);
      EXPECT_EQ(tiles.basis_layout(), BasisLayout::point_tiles);
      EXPECT_EQ(rows.point_blocks(), *block_bytes ? 2 : 1);
      SCOPED_TRACE(std::string(*block_bytes ? "blocks" : "one block") +
                   (precision == BasisPrecision::float16 ? ", 16-bit" : ", 32-bit"));
      for (auto* r : {&rows, &tiles}) r->set_placements(grid_placements(rest_bounds(basis), 2));
      const VertexDump a = rows.evaluate(frames), b = tiles.evaluate(frames);
      EXPECT_EQ(a.positions, b.positions);
      EXPECT_EQ(a.radiance, b.radiance);
      for (auto path : {Evaluation::compute_pass, Evaluation::in_draw, Evaluation::per_point_pass}) {
        rows.set_evaluation(path);
        tiles.set_evaluation(path);
        EXPECT_EQ(max_channel_difference(rows.render(frames), tiles.render(frames)), 0);
      }
      ::unsetenv("PHASECAST_MAX_STORAGE_BLOCK_BYTES");
    }
  }
}

// The compute pass reads its buffers as storage buffers or as buffer
// textures over them (llvmpipe's default): the same values summed in the same
// order, so the same bits, with 32- and 16-bit bases, in point rows and point
// tiles, with and without an appearance model (the fallback reads the normals
// and the lights); point blocks read storage buffers whatever was set.
TEST(GlEvaluation, BothComputeReadsGiveTheSameBits) {
  auto backend = make_render_backend("osmesa", 96, 96);
  for (bool appearance : {true, false}) {
    testing::PlateOptions options;
    options.appearance = appearance;
    const auto package = testing::make_plate_package(options);
    const auto basis = basis_from_package(package, 1);
    const std::vector<FrameState> frames{portrait_frames(package, 0)[40], portrait_frames(package, 3)[20],
                                         portrait_frames(package, 4)[10]};
    for (auto precision : {BasisPrecision::float32, BasisPrecision::float16}) {
      for (auto layout : {BasisLayout::point_rows, BasisLayout::point_tiles}) {
        SCOPED_TRACE(std::string(appearance ? "appearance, " : "no appearance, ") +
                     (precision == BasisPrecision::float16 ? "16-bit, " : "32-bit, ") +
                     basis_layout_name(layout));
        LowRankRenderer storage(*backend, basis, 96, 96, precision, layout);
        LowRankRenderer textures(*backend, basis, 96, 96, precision, layout);
        EXPECT_EQ(textures.compute_reads(), ComputeReads::buffer_textures) << "llvmpipe's default";
        storage.set_compute_reads(ComputeReads::storage_buffers);
        for (auto* r : {&storage, &textures}) {
          r->set_evaluation(Evaluation::compute_pass);
          r->set_placements(grid_placements(rest_bounds(basis), 3));
        }
        EXPECT_EQ(storage.compute_reads(), ComputeReads::storage_buffers);
        const VertexDump a = storage.evaluate(frames), b = textures.evaluate(frames);
        EXPECT_EQ(a.positions, b.positions);
        EXPECT_EQ(a.radiance, b.radiance);
        EXPECT_EQ(max_channel_difference(storage.render(frames), textures.render(frames)), 0);
      }
    }
  }
  const auto package = testing::make_plate_package();
  const auto basis = basis_from_package(package, 1);
  const std::size_t u_a_row = 48 * 4 * static_cast<std::size_t>((basis.rank_a + 3) / 4) * sizeof(float);
  ::setenv("PHASECAST_MAX_STORAGE_BLOCK_BYTES", std::to_string(64 * u_a_row).c_str(), 1);
  LowRankRenderer blocks(*backend, basis, 96, 96);
  ::unsetenv("PHASECAST_MAX_STORAGE_BLOCK_BYTES");
  blocks.set_evaluation(Evaluation::compute_pass);
  ASSERT_EQ(blocks.point_blocks(), 2);
  EXPECT_EQ(blocks.compute_reads(), ComputeReads::storage_buffers);
}

// --half stores U_u and U_a as 16-bit floats: the points move and shine as
// with 32-bit bases up to half precision's relative error (2^-11) on the
// displacement and the transfer, and the GPU holds fewer bytes per point.
TEST(GlEvaluation, HalfBasesAddOnlyHalfPrecisionsError) {
  const auto package = testing::make_plate_package();
  const auto basis = basis_from_package(package, 1);
  auto backend = make_render_backend("osmesa", 64, 64);
  LowRankRenderer full(*backend, basis, 64, 64);
  LowRankRenderer half(*backend, basis, 64, 64, BasisPrecision::float16);
  EXPECT_LT(half.gpu_bytes_per_point(), full.gpu_bytes_per_point());
  const auto r_u4 = static_cast<std::size_t>((basis.rank_u + 3) / 4),
             r_a4 = static_cast<std::size_t>((basis.rank_a + 3) / 4);
  EXPECT_EQ(full.gpu_bytes_per_point() - half.gpu_bytes_per_point(), 24 * r_u4 + 384 * r_a4);
  double worst_position = 0, worst_radiance = 0;
  for (int irf : {0, 3}) {
    for (const auto& f : portrait_frames(package, irf)) {
      if (f.frame % 10 != 5) continue;
      const VertexDump a = full.evaluate(f), b = half.evaluate(f);
      const FrameState rest{f.frame, std::vector<float>(f.q_u.size()), f.q_a, f.support};
      const VertexDump undeformed = full.evaluate(rest);
      double displacement = 1e-9, brightest = 1e-9;
      for (std::size_t k = 0; k < a.positions.size(); ++k) {
        displacement = std::max(displacement, double(std::abs(a.positions[k] - undeformed.positions[k])));
        brightest = std::max(brightest, double(std::abs(a.radiance[k])));
      }
      for (std::size_t k = 0; k < a.positions.size(); ++k) {
        worst_position = std::max(worst_position, std::abs(a.positions[k] - b.positions[k]) / displacement);
        worst_radiance = std::max(worst_radiance, std::abs(a.radiance[k] - b.radiance[k]) / brightest);
      }
    }
  }
  ::testing::Test::RecordProperty("half_relative_position_error", std::to_string(worst_position));
  ::testing::Test::RecordProperty("half_relative_radiance_error", std::to_string(worst_radiance));
  EXPECT_GT(worst_position, 0) << "the 16-bit bases are in use";
  EXPECT_LT(worst_position, 4e-3) << "of the largest displacement";
  EXPECT_GT(worst_radiance, 0);
  EXPECT_LT(worst_radiance, 4e-3) << "of the brightest radiance";
}

TEST(GlEvaluation, StaticMeshDrawsTheSameImage) {
  const auto package = testing::make_plate_package();
  const auto basis = basis_from_package(package, 1);
  auto backend = make_render_backend("osmesa", 96, 96);
  LowRankRenderer renderer(*backend, basis, 96, 96);
  const FrameState f = portrait_frames(package, 4)[20];
  const Image low_rank = renderer.render(f);
  renderer.set_static_mesh(renderer.evaluate(f));
  renderer.draw_static();
  const Image reference = renderer.read_pixels();
  EXPECT_LE(max_channel_difference(low_rank, reference), 1);
}

TEST(GlEvaluation, EglBackendAgreesWithOsmesa) {
  const auto package = testing::make_plate_package();
  const auto basis = basis_from_package(package, 1);
  std::unique_ptr<RenderBackend> egl;
  try {
    egl = make_render_backend("egl", 48, 48);
  } catch (const RenderError& e) {
    GTEST_SKIP() << e.what();
  }
  LowRankRenderer renderer(*egl, basis, 48, 48);
  const FrameState f = portrait_frames(package, 1)[30];
  expect_positions_match(renderer.evaluate(f), cpu_positions(basis, f.q_u, f.support));
}

}  // namespace
}  // namespace phasecast::client
