#!/usr/bin/env node
// Loads a .glb written by phasecast-export with three.js's GLTFLoader, under
// Node and without a browser, and checks what a three.js page would get
// (docs/gltf.md, "The three.js check"): a node `support` with the morphed mesh
// as its child, r_u morph targets named q_u[k], one AnimationClip whose tracks
// all find their node when the file has an animation. It then plays the clip
// with an AnimationMixer to one keyframe and evaluates the mesh's vertices in
// the world, to write them (--out) or compare them (--expected) with positions
// computed elsewhere (tests/client/check_gltf_export.py: x̄ + U_u q_u from the
// package). Exits 0 when every check passes, 1 when one fails (or the file
// cannot be read or loaded), 2 on bad usage.
//
//   node scripts/gltf-validate/load-three.mjs FILE.glb [--r-u N] [--keyframe I]
//        [--out POSITIONS.json] [--expected POSITIONS.json] [--tolerance REL]
//
// No DOM shims are needed: the exported files have no images or textures
// (vertex colours, KHR_materials_unlit), so GLTFLoader never reaches an image
// decoder, and parse() on the file's bytes avoids fetch(), which Node cannot
// do for file paths. three only builds a TextureLoader in that case and never
// calls it.

import { readFile, writeFile } from "node:fs/promises";
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";

const usage =
  "usage: load-three.mjs FILE.glb [--r-u N] [--keyframe I] [--out POSITIONS.json] " +
  "[--expected POSITIONS.json] [--tolerance REL]\n" +
  "  --r-u N           morph targets expected (default: r_u of scenes[0].extras)\n" +
  "  --keyframe I      play the animation to keyframe I (default 0; the rest pose without an animation)\n" +
  "  --out FILE        write the world positions of the support's mesh there as JSON\n" +
  "  --expected FILE   compare them with the \"positions\" ([[x, y, z], ...]) of that JSON\n" +
  "  --tolerance REL   largest error relative to max |expected coordinate| (default 1e-5)";

// A failed check of the file (exit 1), as opposed to bad usage (exit 2).
class CheckFailed extends Error {}

function check(condition, message) {
  if (!condition) throw new CheckFailed(message);
}

function badUsage(message) {
  console.error(`load-three.mjs: ${message}\n${usage}`);
  process.exit(2);
}

function wholeNumber(text, option) {
  if (!/^[0-9]+$/.test(text ?? "")) badUsage(`${option} needs a whole number, got '${text ?? ""}'`);
  return Number(text);
}

function parseArgs(argv) {
  const options = { file: null, rU: null, keyframe: null, out: null, expected: null, tolerance: 1e-5 };
  for (let i = 0; i < argv.length; ++i) {
    const arg = argv[i];
    const value = () => (i + 1 < argv.length ? argv[++i] : badUsage(`${arg} needs a value`));
    if (arg === "--help" || arg === "-h") {
      console.log(usage);
      process.exit(0);
    } else if (arg === "--r-u") options.rU = wholeNumber(value(), arg);
    else if (arg === "--keyframe") options.keyframe = wholeNumber(value(), arg);
    else if (arg === "--out") options.out = value();
    else if (arg === "--expected") options.expected = value();
    else if (arg === "--tolerance") {
      options.tolerance = Number(value());
      if (!(options.tolerance >= 0)) badUsage(`--tolerance needs a number >= 0, got '${argv[i]}'`);
    } else if (arg.startsWith("-")) badUsage(`unknown option '${arg}'`);
    else if (options.file === null) options.file = arg;
    else badUsage(`more than one file given ('${options.file}', '${arg}')`);
  }
  if (options.file === null) badUsage("no file given");
  return options;
}

async function load(file) {
  let bytes;
  try {
    bytes = await readFile(file);
  } catch (e) {
    throw new CheckFailed(`${file}: cannot be read (${e.code ?? e.message})`);
  }
  // A Buffer may be a view into a larger pool: hand the loader exactly the file.
  const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  try {
    return await new GLTFLoader().parseAsync(buffer, "");
  } catch (e) {
    throw new CheckFailed(`${file}: three.js's GLTFLoader cannot load it (${e.message ?? e})`);
  }
}

function printGraph(object, depth = 0) {
  let what = `${object.type} "${object.name}"`;
  if (object.isMesh) {
    const targets = object.geometry.morphAttributes.position?.length ?? 0;
    what += ` (${object.geometry.attributes.position.count} vertices, ${targets} morph targets)`;
  }
  console.log(`  ${"  ".repeat(depth)}${what}`);
  for (const child of object.children) printGraph(child, depth + 1);
}

// The scene graph docs/gltf.md describes: the support node and the mesh under it.
function checkGraph(gltf, rUOption) {
  const supports = [];
  gltf.scene.traverse((o) => o.name === "support" && supports.push(o));
  check(supports.length === 1, `${supports.length} nodes named 'support' (expected 1)`);
  const support = supports[0];
  const meshes = support.children.filter((c) => c.isMesh);
  check(meshes.length === 1, `'support' has ${meshes.length} mesh children (expected 1)`);
  const mesh = meshes[0];

  const extrasRU = gltf.scene.userData?.r_u; // scenes[0].extras become the scene's userData
  const rU = rUOption ?? extrasRU;
  check(Number.isInteger(rU), "r_u is neither given with --r-u nor in scenes[0].extras");
  if (rUOption !== null && extrasRU !== undefined) {
    check(extrasRU === rUOption, `scenes[0].extras.r_u is ${extrasRU}, --r-u ${rUOption}`);
  }
  const targets = mesh.geometry.morphAttributes.position ?? [];
  check(targets.length === rU, `the mesh has ${targets.length} morph targets, r_u = ${rU}`);
  check((mesh.morphTargetInfluences ?? []).length === rU,
        `the mesh has ${(mesh.morphTargetInfluences ?? []).length} morph influences, r_u = ${rU}`);
  // Blender and three.js show targets by these names (mesh.extras.targetNames).
  for (let k = 0; k < rU; ++k) {
    check(mesh.morphTargetDictionary?.[`q_u[${k}]`] === k, `morph target ${k} is not named 'q_u[${k}]'`);
  }
  return { support, mesh, rU };
}

// One clip when the file has an animation, none otherwise; every track must
// find its object, or the mixer would silently animate nothing.
function checkAnimation(gltf, mesh, rU) {
  const inFile = gltf.parser.json.animations?.length ?? 0;
  check(gltf.animations.length === inFile,
        `${gltf.animations.length} AnimationClips from ${inFile} glTF animations`);
  check(inFile <= 1, `${inFile} animations (phasecast-export writes at most one)`);
  if (inFile === 0) return null;
  const clip = gltf.animations[0];
  console.log(`animation: clip "${clip.name}", ${clip.duration.toFixed(3)} s, ${clip.tracks.length} tracks`);
  let morphTrack = null;
  for (const track of clip.tracks) {
    const parsed = THREE.PropertyBinding.parseTrackName(track.name);
    const node = THREE.PropertyBinding.findNode(gltf.scene, parsed.nodeName);
    check(node, `track '${track.name}' finds no object named '${parsed.nodeName}'`);
    console.log(`  ${track.name}: ${track.times.length} keyframes (${track.getInterpolation() === THREE.InterpolateLinear ? "linear" : "not linear"})`);
    if (node === mesh && parsed.propertyName === "morphTargetInfluences") morphTrack = track;
  }
  check(morphTrack, "no track animates the mesh's morphTargetInfluences");
  check(morphTrack.values.length === morphTrack.times.length * rU,
        `the weights track has ${morphTrack.values.length} values for ${morphTrack.times.length} keyframes of ${rU}`);
  return { clip, morphTrack };
}

// Plays the clip from its start to keyframe `index` as a page would, with an
// AnimationMixer, and checks the influences it leaves are that keyframe's.
function playTo(gltf, mesh, animation, index) {
  const { clip, morphTrack } = animation;
  check(index < morphTrack.times.length, `--keyframe ${index}: the clip has ${morphTrack.times.length} keyframes`);
  const time = morphTrack.times[index];
  const mixer = new THREE.AnimationMixer(gltf.scene);
  const action = mixer.clipAction(clip);
  // Played once and held: with the default LoopRepeat the last keyframe's
  // time (= the duration) would wrap to the first.
  action.setLoop(THREE.LoopOnce, 1);
  action.clampWhenFinished = true;
  action.play();
  mixer.setTime(time);
  const rU = mesh.morphTargetInfluences.length;
  for (let k = 0; k < rU; ++k) {
    const keyed = morphTrack.values[index * rU + k];
    const got = mesh.morphTargetInfluences[k];
    check(Math.abs(got - keyed) <= 1e-6 * Math.max(1, Math.abs(keyed)),
          `after the mixer: influence ${k} is ${got}, keyframe ${index} has ${keyed}`);
  }
  return time;
}

// World positions of the mesh's vertices: base + Σ_k w_k target_k (glTF
// targets are displacements, which three marks morphTargetsRelative), then
// matrixWorld. Done here rather than by three's renderer, which runs on the GPU.
function worldPositions(gltf, mesh) {
  gltf.scene.updateMatrixWorld(true);
  const geometry = mesh.geometry;
  const base = geometry.attributes.position;
  const targets = geometry.morphAttributes.position;
  const weights = mesh.morphTargetInfluences;
  const relative = geometry.morphTargetsRelative;
  const local = new THREE.Vector3();
  const mine = new THREE.Vector3();
  const threes = new THREE.Vector3();
  const positions = [];
  let disagreement = 0;
  for (let i = 0; i < base.count; ++i) {
    const b = [base.getX(i), base.getY(i), base.getZ(i)];
    const p = [...b];
    for (let k = 0; k < targets.length; ++k) {
      const t = [targets[k].getX(i), targets[k].getY(i), targets[k].getZ(i)];
      for (let c = 0; c < 3; ++c) p[c] += weights[k] * (relative ? t[c] : t[c] - b[c]);
    }
    local.fromArray(p);
    // three's own CPU evaluation (what raycasting uses) must agree with ours:
    // this is what ties the formula above to three's meaning of the targets.
    mesh.getVertexPosition(i, threes);
    disagreement = Math.max(disagreement, local.distanceTo(threes));
    mine.copy(local).applyMatrix4(mesh.matrixWorld);
    positions.push(mine.toArray());
  }
  return { positions, disagreement };
}

function compare(positions, expected, tolerance) {
  check(Array.isArray(expected) && expected.length === positions.length,
        `${positions.length} vertices, the expected positions have ${expected?.length}`);
  let scale = 0;
  let worst = 0;
  let worstIndex = -1;
  for (let i = 0; i < expected.length; ++i) {
    for (let c = 0; c < 3; ++c) {
      scale = Math.max(scale, Math.abs(expected[i][c]));
      const error = Math.abs(positions[i][c] - expected[i][c]);
      if (error > worst) [worst, worstIndex] = [error, i];
    }
  }
  const limit = tolerance * scale;
  const line = `worst error ${worst.toExponential(3)} (vertex ${worstIndex}), limit ${limit.toExponential(3)} = ` +
    `${tolerance} x max |coordinate| ${scale.toPrecision(4)}`;
  check(worst <= limit, `three.js positions differ from the expected ones: ${line}`);
  console.log(`positions match the expected ones: ${line}`);
}

async function main() {
  const options = parseArgs(process.argv.slice(2));
  let expected = null;
  if (options.expected !== null) {
    try {
      expected = JSON.parse(await readFile(options.expected, "utf8")).positions;
    } catch (e) {
      badUsage(`--expected ${options.expected}: not a readable JSON file (${e.message})`);
    }
  }
  const gltf = await load(options.file);
  console.log(`${options.file}: loaded by three.js r${THREE.REVISION} GLTFLoader`);
  printGraph(gltf.scene);
  const { support, mesh, rU } = checkGraph(gltf, options.rU);
  console.log(`scene graph: 'support' -> mesh '${mesh.name}' with ${rU} morph targets q_u[0..${rU - 1}]`);

  const animation = checkAnimation(gltf, mesh, rU);
  let time = null;
  if (animation) time = playTo(gltf, mesh, animation, options.keyframe ?? 0);
  else check(options.keyframe === null, `--keyframe ${options.keyframe}: the file has no animation`);

  const { positions, disagreement } = worldPositions(gltf, mesh);
  const size = positions.reduce((m, p) => Math.max(m, ...p.map(Math.abs)), 0);
  check(disagreement <= 1e-9 * Math.max(size, 1e-30),
        `mean + sum w_k target_k differs from three's Mesh.getVertexPosition by ${disagreement}`);
  const weights = Array.from(mesh.morphTargetInfluences);
  const largest = weights.reduce((m, w) => Math.max(m, Math.abs(w)), 0);
  console.log(
    (animation ? `keyframe ${options.keyframe ?? 0} (t = ${time.toFixed(4)} s)` : "rest pose (no animation)") +
      `: largest |weight| ${largest.toPrecision(4)}, support at (${support.position.toArray().map((v) => v.toPrecision(4)).join(", ")}) ` +
      `turned ${THREE.MathUtils.radToDeg(2 * Math.acos(Math.min(1, Math.abs(support.quaternion.w)))).toFixed(1)} deg; ` +
      `${positions.length} world positions, agreeing with three's getVertexPosition to ${disagreement.toExponential(2)}`,
  );

  if (options.out !== null) {
    const result = {
      file: options.file,
      three: THREE.REVISION,
      keyframe: animation ? options.keyframe ?? 0 : null,
      time,
      r_u: rU,
      weights,
      support: { position: support.position.toArray(), quaternion: support.quaternion.toArray() },
      positions,
    };
    await writeFile(options.out, JSON.stringify(result) + "\n");
  }
  if (expected !== null) compare(positions, expected, options.tolerance);
}

try {
  await main();
} catch (e) {
  if (!(e instanceof CheckFailed)) throw e;
  console.error(`load-three.mjs: ${e.message}`);
  process.exit(1);
}
