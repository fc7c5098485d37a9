// phasecast-export: a package (and a recorded session) as binary glTF 2.0 for
// Blender, three.js, Unity or Unreal. See docs/gltf.md.

#include "phasecast/client/gltf_export.h"
#include "phasecast/client/sh_light.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <exception>
#include <iostream>

int main(int argc, char** argv) {
  using phasecast::client::GltfExportOptions;
  CLI::App app{
      "phasecast-export: writes a scene package as binary glTF 2.0 (.glb): the mesh at the mean shape "
      "x_bar, one morph target per column of U_u, the support as a parent node, vertex colours from the "
      "mean transfer; with --recording, one animation whose morph weights are q_u (eq. 7) and whose "
      "support node follows the recorded support transform."};
  GltfExportOptions o;
  std::string package, out, recording;
  std::uint32_t instance = 0;
  app.add_option("package", package, "scene package (.h5)")->required();
  app.add_option("-o,--out", out, "binary glTF file to write (.glb)")->required();
  auto* recording_opt =
      app.add_option("--recording", recording, "session recorded by phasecast-server --record (.phcrec)");
  auto* instance_opt =
      app.add_option("--instance", instance,
                     "recorded instance to animate (default: the first instance of the package's scene)");
  instance_opt->needs(recording_opt);
  app.add_option("--light", o.light,
                 fmt::format("SH light probe the vertex colours are lit by: {} (default: the scene's [view] "
                             "light, else grace, as phasecast-render)",
                             fmt::join(phasecast::client::light_probe_names(), ", ")));
  // Bad usage exits 2, as opposed to 1, a failed export.
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-export"))
    return *status;
  try {
    o.package = package;
    o.out = out;
    if (!recording.empty()) o.recording = recording;
    if (*instance_opt) o.instance = instance;
    const auto summary = phasecast::client::export_gltf(o);
    std::cout << phasecast::client::describe(summary, o.out);
  } catch (const std::exception& e) {
    std::cerr << "phasecast-export: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
