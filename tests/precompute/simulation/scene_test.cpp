// Scene files: the shipped tiny scenes load, palette kinematics map onto the
// package's terms, and every invalid file is rejected with one line naming
// the file and the field.

#include "phasecast/precompute/simulation/scene.h"
#include "error_of.h"
#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "run_tool.h"
#include "source_tree.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <string>

namespace phasecast::precompute {
namespace {

using phasecast::testing::error_of;

const std::filesystem::path kScenes = phasecast::testing::scenes_dir();

TEST(Scene, TinyClothDoorLoads) {
  const Scene s = load_scene_file(kScenes / "tiny/cloth_door.toml");
  EXPECT_EQ(s.name, "cloth_door_tiny");
  EXPECT_EQ(s.model.vertices(), 6 * 8);
  EXPECT_EQ(s.model.membranes.size(), 2u * 5 * 7);
  EXPECT_EQ(s.model.surface.rows(), 2 * 5 * 7);
  int pinned = 0;
  for (auto p : s.model.pinned) pinned += p;
  EXPECT_EQ(pinned, 6);  // the top row on the rail
  ASSERT_EQ(s.palette.size(), 3u);
  EXPECT_EQ(s.palette_index("open"), 2);
  EXPECT_NEAR(s.model.mass.sum(), 0.2 * 0.5 * 0.7, 1e-12);  // density x area
}

TEST(Scene, DoorPaletteMapsToRotationalKinematicsWithItsRange) {
  const Scene s = load_scene_file(kScenes / "tiny/cloth_door.toml");
  const auto open = entry_kinematics(s, s.palette_index("open"));
  EXPECT_TRUE(open.rotational);
  EXPECT_FLOAT_EQ(open.rate, 1.5f);
  EXPECT_FLOAT_EQ(open.axis[1], -1.0f);
  EXPECT_FLOAT_EQ(open.range_min, 0.0f);
  EXPECT_NEAR(open.range_max, 3.14159265f / 2, 1e-6);
  EXPECT_FLOAT_EQ(entry_kinematics(s, s.palette_index("close")).rate, -1.5f);
  EXPECT_FLOAT_EQ(entry_kinematics(s, s.palette_index("stop")).rate, 0.0f);
}

TEST(Scene, ScheduleParsesEntriesAndDurations) {
  const Scene s = load_scene_file(kScenes / "tiny/cloth_door.toml");
  const auto items = parse_schedule("open 1.5; stop 2;close 0.5 ;", s);
  ASSERT_EQ(items.size(), 3u);
  EXPECT_EQ(items[0].entry, 2);
  EXPECT_DOUBLE_EQ(items[1].duration, 2.0);
  EXPECT_EQ(items[2].entry, 0);
}

TEST(Scene, BadSchedulesAreRejectedWithTheItem) {
  const Scene s = load_scene_file(kScenes / "tiny/cloth_door.toml");
  EXPECT_NE(error_of([&] {
              parse_schedule("open 1; slam 2", s);
            }).find("unknown palette entry 'slam' (expected one of: close, stop, open)"),
            std::string::npos);
  EXPECT_EQ(error_of([&] { parse_schedule("open fast", s); }),
            "schedule item 'open fast': expected '<palette entry> <seconds > 0>'");
  EXPECT_EQ(error_of([&] { parse_schedule("open -1", s); }),
            "schedule item 'open -1': expected '<palette entry> <seconds > 0>'");
  EXPECT_EQ(error_of([&] { parse_schedule("open 0.001", s); }),
            "schedule item 'open 0.001': shorter than one frame (0.02 s)");
}

// A valid small scene; each rejection test edits one line of it.
const std::string kValid = R"(name = "t"
[simulation]
frame_dt = 0.02
[support]
motion = "rotational"
axis = [0, 1, 0]
[[body]]
name = "cloth"
energies = ["membrane", "bending"]
density = 0.2
young = 100
bending = 1e-5
grid = { origin = [0, 0, 0], u = [1, 0, 0], v = [0, -1, 0], cells = [2, 2] }
pin = { min = [-1, -0.1, -1], max = [2, 0.1, 1] }
[[palette]]
name = "go"
alpha_impulse = [0, 1, 0]
alpha_forcing = [0, 1, 0]
)";

std::filesystem::path write_scene(const std::string& name, const std::string& text) {
  const auto dir = testing::scratch_dir("scene_" + name);
  std::ofstream(dir / "scene.toml") << text;
  return dir / "scene.toml";
}

std::string edited(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

std::string rejection(const std::string& name, const std::string& text) {
  const auto path = write_scene(name, text);
  std::string message = error_of([&] { load_scene_file(path); });
  EXPECT_EQ(message.find('\n'), std::string::npos) << "one line: " << message;
  EXPECT_EQ(message.rfind(path.string(), 0), 0u) << "names the file: " << message;
  return message.substr(std::min(message.size(), path.string().size()));
}

TEST(SceneErrors, ValidBaseLoads) {
  EXPECT_NO_THROW(load_scene_file(write_scene("valid", kValid)));
}

// [demo] names the demo's script relative to the scene file, and its seed;
// every shipped scene has one (scripts/demo --scene refuses a scene without),
// generated ones included.
TEST(Scene, DemoSectionNamesTheScriptAndTheSeed) {
  for (const auto& dir : {kScenes, kScenes / "tiny", kScenes / "paper"}) {
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      if (entry.path().extension() != ".toml") continue;
      const Scene s = load_scene_file(entry.path());
      ASSERT_TRUE(s.demo) << entry.path();
      EXPECT_TRUE(std::filesystem::is_regular_file(s.demo->script)) << s.demo->script;
      EXPECT_EQ(s.demo->script.parent_path(),
                std::filesystem::absolute(kScenes / "scripts").lexically_normal());
    }
  }
  EXPECT_EQ(load_scene_file(kScenes / "toy_dashboard.toml").demo->seed, 2);
  EXPECT_FALSE(load_scene_file(write_scene("no_demo", kValid)).demo);
  const auto with_demo = [](const std::string& body) { return kValid + "\n[demo]\n" + body + "\n"; };
  const auto path = write_scene("demo_ok", with_demo("script = \"scene.toml\"\nseed = 7"));
  const Scene s = load_scene_file(path);
  EXPECT_EQ(s.demo->script, std::filesystem::absolute(path).lexically_normal());
  EXPECT_EQ(s.demo->seed, 7);
  EXPECT_EQ(rejection("demo_seed", with_demo("script = \"scene.toml\"\nseed = -1")),
            ": field 'demo.seed': expected a whole number >= 0, got integer -1");
  EXPECT_EQ(rejection("demo_script", with_demo("script = 3")),
            ": field 'demo.script': expected a string, got integer 3");
  EXPECT_NE(rejection("demo_key", with_demo("script = \"scene.toml\"\nsed = 2")).find("demo.sed"),
            std::string::npos);
}

// [view]: the camera, floor, light and exposure clients use where their flags are absent.
TEST(Scene, ViewSectionSetsCameraFloorLightAndExposure) {
  const auto with_view = [](const std::string& body) { return kValid + "\n[view]\n" + body + "\n"; };
  EXPECT_FALSE(load_scene_file(write_scene("no_view", kValid)).view);
  const Scene s = load_scene_file(write_scene(
      "view_ok", with_view("eye = [0, 1, 3]\ntarget = [0, 0.5, 0]\nfov = 30\nfloor = -1.5\nlight = \"sun\"\n"
                           "exposure = 1.4")));
  ASSERT_TRUE(s.view && s.view->eye && s.view->target);
  EXPECT_EQ(*s.view->eye, Eigen::Vector3d(0, 1, 3));
  EXPECT_EQ(s.view->up, Eigen::Vector3d::UnitY());
  EXPECT_EQ(s.view->fov_y_deg, 30);
  EXPECT_TRUE(s.view->floor);
  EXPECT_EQ(s.view->floor_height, -1.5);
  EXPECT_EQ(s.view->light, "sun");
  EXPECT_EQ(s.view->exposure, 1.4);
  EXPECT_FALSE(load_scene_file(write_scene("view_none", with_view("floor = \"none\""))).view->floor);
  EXPECT_EQ(rejection("view_floor", with_view("floor = \"off\"")),
            ": field 'view.floor': expected a height (y, m) or \"none\", got string \"off\"");
  EXPECT_EQ(rejection("view_light", with_view("light = \"moon\"")),
            ": field 'view.light': expected one of grace, sky, sun, white, got string \"moon\"");
  EXPECT_EQ(rejection("view_eye", with_view("eye = [0, 1, 3]")),
            ": field 'view.target': expected eye and target together, got nothing (missing)");
  EXPECT_EQ(
      rejection("view_fov_alone", with_view("fov = 30")),
      ": field 'view.fov': expected eye and target with it (they make the camera together), got integer 30");
  EXPECT_EQ(rejection("view_fov", with_view("eye = [0, 1, 3]\ntarget = [0, 0, 0]\nfov = 200")),
            ": field 'view.fov': expected a vertical field of view in (0, 180) degrees, got integer 200");
  EXPECT_NE(rejection("view_key", with_view("exposur = 2")).find("view.exposur"), std::string::npos);
}

// A Blender scene whose .blend is missing says how to make it, in one line.
TEST(SceneErrors, MissingBlendSaysHowToMakeIt) {
  std::ifstream in(kScenes / "tiny/blender/cloth_door.toml");
  const std::string text{std::istreambuf_iterator<char>(in), {}};
  const std::string message = rejection("blend_missing", text);
  EXPECT_NE(message.find(": field 'simulator.blend': "), std::string::npos) << message;
  EXPECT_NE(message.find("cloth_door.blend does not exist (expected an existing .blend file; make it with: "
                         "blender -b --factory-startup --python "),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("--cells 5 7)"), std::string::npos) << message;
  EXPECT_EQ(message.find(", got"), std::string::npos) << message;
}

TEST(SceneErrors, MissingField) {
  EXPECT_EQ(rejection("missing", edited(kValid, "frame_dt = 0.02", "")),
            ": field 'simulation.frame_dt': expected a positive number, got nothing (missing)");
}

TEST(SceneErrors, WrongType) {
  EXPECT_EQ(rejection("type", edited(kValid, "density = 0.2", "density = \"heavy\"")),
            ": field 'body[0].density': expected a positive number, got string \"heavy\"");
}

TEST(SceneErrors, NaNValue) {
  EXPECT_EQ(rejection("nan", edited(kValid, "young = 100", "young = nan")),
            ": field 'body[0].young': expected a positive number, got number nan");
  EXPECT_EQ(rejection("nanvec", edited(kValid, "alpha_forcing = [0, 1, 0]", "alpha_forcing = [0, nan, 0]")),
            ": field 'palette[0].alpha_forcing': expected an array of 3 finite numbers, got array of 3");
}

TEST(SceneErrors, UnknownLinearSolver) {
  const std::string message =
      rejection("solver", edited(kValid, "frame_dt = 0.02", "frame_dt = 0.02\nlinear_solver = \"dense\""));
  EXPECT_NE(message.find("'simulation.linear_solver': expected \"simplicial\" or \"supernodal\""),
            std::string::npos)
      << message;
}

TEST(SceneErrors, BadAlbedoAndProps) {
  EXPECT_EQ(rejection("albedo", edited(kValid, "density = 0.2", "density = 0.2\nalbedo = [0.5, 1.5, 0.5]")),
            ": field 'body[0].albedo': expected [r, g, b] with each in [0, 1], got array of 3");
  EXPECT_EQ(rejection("albedo2", edited(kValid, "density = 0.2", "density = 0.2\nalbedo = 0.5")),
            ": field 'body[0].albedo': expected [r, g, b] with each in [0, 1], got number 0.5");
  const std::string box = "[[obstacle]]\nname = \"b\"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n";
  EXPECT_EQ(rejection("cell", kValid + box + "cell = -0.1\n"),
            ": field 'obstacle[0].cell': expected a tessellation edge length >= 0 (m), got number -0.1");
  EXPECT_EQ(
      rejection("cells", kValid + box + "cell = 0.001\n"),
      ": field 'obstacle[0].cell': expected at most 256 cells along an edge of the box, got number 0.001");
  EXPECT_EQ(rejection("eps", kValid + "[appearance]\neps_a = 2\n"),
            ": field 'appearance.eps_a': expected a number in (0, 1), got integer 2");
  EXPECT_EQ(rejection("clusters", kValid + "[appearance]\nclusters = 0\n"),
            ": field 'appearance.clusters': expected a positive integer, got integer 0");
  EXPECT_EQ(rejection("rays", kValid + "[appearance]\nrays = 2000000\n"),
            ": field 'appearance.rays': expected a positive integer, got integer 2000000");
  EXPECT_EQ(rejection("rays0", kValid + "[appearance]\nrays = 0\n"),
            ": field 'appearance.rays': expected a positive integer, got integer 0");
}

TEST(SceneErrors, UnknownEnergyName) {
  EXPECT_EQ(rejection("energy", edited(kValid, "\"bending\"]", "\"stretchy\"]")),
            ": field 'body[0].energies': expected energy names among membrane, bending, rod, tet_fem, "
            "tet_neo_hookean ('stretchy' is unknown), got array of 2");
}

TEST(SceneErrors, TetEnergiesOnlyOnTetMeshesAndOneAtATime) {
  EXPECT_EQ(rejection("snhgrid", edited(kValid, "\"bending\"]", "\"tet_neo_hookean\"]")),
            ": field 'body[0].energies': expected 'tet_neo_hookean' only on tetgen meshes, got array of 2");
  EXPECT_EQ(
      rejection("twotets",
                edited(kValid, "[\"membrane\", \"bending\"]", "[\"tet_fem\", \"tet_neo_hookean\"]")),
      ": field 'body[0].energies': expected one tet energy, 'tet_fem' or 'tet_neo_hookean' (each is a whole "
      "material), got array of 2");
}

TEST(SceneErrors, UnknownIntegratorAndUnstableNewmarkParameters) {
  const auto with = [](const std::string& lines) {
    return edited(kValid, "frame_dt = 0.02", "frame_dt = 0.02\n" + lines);
  };
  EXPECT_EQ(
      rejection("integrator", with("integrator = \"verlet\"")),
      ": field 'simulation.integrator': expected \"backward_euler\" or \"newmark\", got string \"verlet\"");
  EXPECT_EQ(rejection("gamma", with("integrator = \"newmark\"\nnewmark_gamma = 0.4")),
            ": field 'simulation.newmark_gamma': expected a number >= 0.5, got number 0.4");
  EXPECT_EQ(rejection("beta", with("integrator = \"newmark\"\nnewmark_beta = 0.2")),
            ": field 'simulation.newmark_beta': expected a number >= (newmark_gamma + 1/2)^2 / 4 = 0.25, got "
            "number 0.2");
  EXPECT_EQ(
      rejection("beta2", with("integrator = \"newmark\"\nnewmark_gamma = 0.75\nnewmark_beta = 0.3")),
      ": field 'simulation.newmark_beta': expected a number >= (newmark_gamma + 1/2)^2 / 4 = 0.390625, got "
      "number 0.3");
  EXPECT_EQ(
      rejection("eulerbeta", with("newmark_beta = 0.3")),
      ": field 'simulation.newmark_beta': expected no value unless integrator = \"newmark\", got number "
      "0.3");
}

TEST(Scene, NewmarkSceneLoadsAndRuns) {
  const Scene euler = load_scene_file(write_scene("euler", kValid));
  EXPECT_EQ(euler.simulation.integrator, Integrator::backward_euler);
  const Scene s = load_scene_file(
      write_scene("newmark", edited(kValid, "frame_dt = 0.02", "frame_dt = 0.02\nintegrator = \"newmark\"")));
  EXPECT_EQ(s.simulation.integrator, Integrator::newmark);
  EXPECT_DOUBLE_EQ(s.simulation.newmark_gamma, 0.5);
  EXPECT_DOUBLE_EQ(s.simulation.newmark_beta, 0.25);
  const auto run = [](const Scene& scene) {
    auto sim = make_simulator(scene);
    sim->impulse(scene.palette[0].alpha_impulse);
    for (int i = 0; i < 25; ++i) sim->step(scene.palette[0].alpha_forcing);
    return sim->state().x;
  };
  const Eigen::VectorXd x = run(s), x_euler = run(euler);
  EXPECT_TRUE(x.allFinite());
  EXPECT_GT((x - s.model.rest).cwiseAbs().maxCoeff(), 1e-3);  // it moved
  EXPECT_GT((x - x_euler).cwiseAbs().maxCoeff(), 1e-6);       // and is not backward Euler
}

// A rod welded to a clamped post at one shared vertex: a ball joint.
const std::string kArmOnPost = R"(name = "arm"
[simulation]
frame_dt = 0.02
settle = 0
[support]
motion = "translational"
axis = [1, 0, 0]
[[body]]
name = "post"
energies = ["rod"]
density = 0.05
young = 3e8
radius = 0.006
polyline = { points = [[0, 0, 0], [0, 0.2, 0]], subdivisions = 4 }
pin = { min = [-0.01, -0.01, -0.01], max = [0.01, 0.06, 0.01] }
[[body]]
name = "arm"
energies = ["rod"]
density = 0.05
young = 3e8
radius = 0.006
polyline = { points = [[0, 0.2, 0], [0.2, 0.2, 0]], subdivisions = 4 }
weld_to = "post"
weld_radius = 1e-4
[[palette]]
name = "still"
alpha_impulse = [0, 0, 0]
alpha_forcing = [0, 0, 0]
)";

// The lowest height the arm's tip reaches in 1 s under gravity.
double lowest_arm_tip(const Scene& scene) {
  auto sim = make_simulator(scene);
  const int tip = scene.bodies[1].vertices.back();
  double lowest = scene.model.rest[3 * tip + 1];
  for (int i = 0; i < 50; ++i) {
    sim->step(Eigen::Vector3d::Zero());
    lowest = std::min(lowest, sim->state().x[3 * tip + 1]);
  }
  return lowest;
}

// A weld alone is a ball joint: the horizontal arm swings down as a pendulum.
// One brace from the arm's second vertex to the post below the joint makes
// the joint stiff in the plane of post and arm (a hinge about the post's axis
// remains, which gravity does not turn), and the arm is a cantilever again: its tip sinks w L^4 / 8EI
// = 0.3 mm under its own weight (w = 0.49 N/m, L = 0.2 m, EI = 0.31 N m^2),
// up to twice that as gravity comes on at once, plus the post's and the brace's give.
TEST(Scene, BraceMakesAWeldAStiffJoint) {
  const double ball = lowest_arm_tip(load_scene_file(write_scene("ball_joint", kArmOnPost)));
  EXPECT_LT(ball, 0.2 - 0.1) << "without a brace the arm hangs from its weld";
  const Scene braced = load_scene_file(write_scene(
      "braced_joint", kArmOnPost + "[[brace]]\nfrom = [0.05, 0.2, 0]\nto = [[0, 0.15, 0]]\nea = 1e4\n"));
  ASSERT_EQ(braced.model.braces.size(), 1u);
  EXPECT_EQ(braced.model.rod_stretch.size(), 8u) << "a brace is not a rod edge: never drawn or exported";
  EXPECT_GT(lowest_arm_tip(braced), 0.2 - 0.002);
}

TEST(SceneErrors, SelfContactFrictionIsACoulombCoefficient) {
  const std::string with_contact = kValid + "[contact]\nself_collision = true\nfriction = 0.4\n";
  EXPECT_DOUBLE_EQ(load_scene_file(write_scene("friction_ok", with_contact)).model.self_friction, 0.4);
  EXPECT_EQ(rejection("friction_bad", edited(with_contact, "friction = 0.4", "friction = -0.1")),
            ": field 'contact.friction': expected a Coulomb coefficient >= 0, got number -0.1");
  EXPECT_EQ(
      rejection("friction_alone", edited(with_contact, "self_collision = true", "self_collision = false")),
      ": field 'contact.friction': expected 0 without self_collision = true (it acts between surfaces in "
      "self-contact), got number 0.4");
}

TEST(SceneErrors, BracesMustEndOnVertices) {
  const std::string braced = kValid + "[[brace]]\nfrom = [0, 0, 0]\nto = [[1, -1, 0]]\nea = 10\n";
  EXPECT_NO_THROW(load_scene_file(write_scene("brace_ok", braced)));
  EXPECT_EQ(rejection("brace_off", edited(braced, "to = [[1, -1, 0]]", "to = [[0.2, -1, 0]]")),
            ": field 'brace[0].to': expected points within snap = 0.0001 m of a body's vertex "
            "([0.2, -1, 0] is 0.2 m from the nearest), got array of 1");
  EXPECT_EQ(rejection("brace_self", edited(braced, "to = [[1, -1, 0]]", "to = [[0, 0, 0]]")),
            ": field 'brace[0].to': expected points at other vertices than 'from', got array of 1");
  EXPECT_EQ(rejection("brace_ea", edited(braced, "ea = 10", "ea = -1")),
            ": field 'brace[0].ea': expected a positive number, got integer -1");
  EXPECT_EQ(rejection("brace_none", edited(braced, "to = [[1, -1, 0]]", "to = []")),
            ": field 'brace[0].to': expected at least one point, got array of 0");
  EXPECT_EQ(rejection("brace_twice", edited(braced, "to = [[1, -1, 0]]", "to = [[1, -1, 0], [1, -1, 0]]")),
            ": field 'brace[0].to': expected points at distinct vertices, got array of 2");
  // The grid's vertices are 0.5 m apart: a 0.6 m snap reaches two of them.
  EXPECT_EQ(
      rejection("brace_ambiguous",
                kValid + "[[brace]]\nfrom = [0.25, 0, 0]\nto = [[1, -1, 0]]\nea = 10\nsnap = 0.6\n"),
      ": field 'brace[0].from': expected a point near one vertex ([0.25, 0, 0] is within snap = 0.6 m of "
      "vertices 0 and 1), got array of 3");
}

TEST(SceneErrors, EnergyOnTheWrongMesh) {
  EXPECT_EQ(rejection("rodgrid", edited(kValid, "\"bending\"]", "\"rod\"]")),
            ": field 'body[0].energies': expected 'rod' only on polyline meshes, got array of 2");
}

// An unknown key names the known one it likely stands for (a typo of it, or
// it with more words), else every key its table knows.
TEST(SceneErrors, MisspeltField) {
  EXPECT_EQ(rejection("typo", edited(kValid, "young = 100", "young = 100\nyoung_modulus = 3")),
            ": field 'body[0].young_modulus': unknown field (did you mean 'body[0].young'?)");
  EXPECT_EQ(rejection("renamed", edited(kValid, "young = 100", "young_modulus = 100")),
            ": field 'body[0].young': expected a positive number, got nothing (missing; the file has "
            "'body[0].young_modulus', misspelt?)");
  const std::string far = rejection("unknown", edited(kValid, "[support]", "[support]\nwobble = 3"));
  EXPECT_EQ(far.substr(0, far.find('(')), ": field 'support.wobble': unknown field ") << far;
  EXPECT_NE(far.find("(expected one of axis, "), std::string::npos) << far;
  EXPECT_NE(far.find("range"), std::string::npos) << far;
}

// A key a typo away from a known one is named with it, whether the known key
// is required (its error names the typo) or optional (the typo's names it).
TEST(SceneErrors, AMisspeltKeyIsNamedWithTheKnownOne) {
  EXPECT_EQ(rejection("typo_required", edited(kValid, "frame_dt = 0.02", "frame_dtt = 0.02")),
            ": field 'simulation.frame_dt': expected a positive number, got nothing (missing; the file has "
            "'simulation.frame_dtt', misspelt?)");
  EXPECT_EQ(rejection("typo_optional", edited(kValid, "young = 100", "young = 100\ndensty = 3")),
            ": field 'body[0].densty': unknown field (did you mean 'body[0].density'?)");
}

TEST(SceneErrors, TomlSyntaxErrorNamesLineAndColumn) {
  EXPECT_NE(rejection("syntax", edited(kValid, "frame_dt = 0.02", "frame_dt = = 0.02")).find(":3:"),
            std::string::npos);
}

TEST(SceneErrors, BadSupportMotion) {
  EXPECT_EQ(rejection("motion", edited(kValid, "\"rotational\"", "\"wobbly\"")),
            ": field 'support.motion': expected \"rotational\" or \"translational\", got string \"wobbly\"");
}

TEST(SceneErrors, AngularVelocityOffTheAxis) {
  EXPECT_EQ(
      rejection("axis", edited(kValid, "alpha_impulse = [0, 1, 0]", "alpha_impulse = [1, 0, 0]")),
      ": field 'palette[0].alpha_impulse': expected an angular velocity along support.axis, got array of 3");
}

TEST(SceneErrors, PinBoxOutsideTheBody) {
  EXPECT_EQ(
      rejection("pin", edited(kValid, "min = [-1, -0.1, -1], max = [2, 0.1, 1]",
                              "min = [5, 5, 5], max = [6, 6, 6]")),
      ": field 'body[0].pin.min': expected a box containing at least one vertex of the body, got array of 3");
}

std::string obj_scene(const std::string& name, const std::string& obj) {
  const auto path = write_scene(
      name, edited(kValid, "grid = { origin = [0, 0, 0], u = [1, 0, 0], v = [0, -1, 0], cells = [2, 2] }",
                   "obj = { path = \"m.obj\" }"));
  std::ofstream(path.parent_path() / "m.obj") << obj;
  std::string message = error_of([&] { load_scene_file(path); });
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  return message.substr(std::min(message.size(), path.string().size()));
}

TEST(SceneErrors, NonManifoldMesh) {
  EXPECT_EQ(
      obj_scene("nonmanifold", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n"),
      ": field 'body[0].obj': non-manifold edge (0, 1) shared by more than 2 triangles");
}

TEST(SceneErrors, DegenerateTriangle) {
  EXPECT_EQ(obj_scene("degenerate", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
            ": field 'body[0].obj': membrane triangle (0, 1, 2) is degenerate (zero area)");
}

TEST(SceneErrors, MalformedObj) {
  const std::string m = obj_scene("badobj", "v 0 0 0\nv 1 0 zero\n");
  EXPECT_NE(m.find("field 'body[0].obj.path'"), std::string::npos) << m;
  EXPECT_NE(m.find("m.obj:2: expected a finite number, got 'zero'"), std::string::npos) << m;
}

TEST(SceneErrors, InvertedTetIsRejectedByTheBuilder) {
  DeformableModel m;
  m.rest.resize(12);
  m.rest << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  EXPECT_EQ(error_of([&] {
              add_tet(m, {0, 2, 1, 3}, {1, 1});
            }),
            "tet (0, 2, 1, 3) is inverted (volume -0.16666666666666666 < 0)");
  EXPECT_NO_THROW(add_tet(m, {0, 1, 2, 3}, {1, 1}));
}

}  // namespace
}  // namespace phasecast::precompute
