#!/usr/bin/env node
// Runs the Khronos glTF validator (npm gltf-validator) on .glb / .gltf files
// and prints its report: one summary line per file, then every issue. Exits 0
// when no file has an error, 1 when one has, 2 on bad usage. Used by the tests
// of phasecast-export (tests/client/CMakeLists.txt) and by hand:
//   node scripts/gltf-validate/validate.mjs out.glb [--json] [--strict]
// --strict also fails on warnings; --json prints the validator's whole report.

import { readFile } from "node:fs/promises";
import { basename } from "node:path";
import validator from "gltf-validator";

const usage = "usage: validate.mjs FILE.glb [FILE ...] [--json] [--strict]";
const SEVERITY = ["error", "warning", "info", "hint"];

function parseArgs(argv) {
  const options = { files: [], json: false, strict: false };
  for (const arg of argv) {
    if (arg === "--json") options.json = true;
    else if (arg === "--strict") options.strict = true;
    else if (arg === "--help" || arg === "-h") {
      console.log(usage);
      process.exit(0);
    } else if (arg.startsWith("-")) {
      console.error(`validate.mjs: unknown option '${arg}' (${usage})`);
      process.exit(2);
    } else options.files.push(arg);
  }
  if (options.files.length === 0) {
    console.error(`validate.mjs: no file given (${usage})`);
    process.exit(2);
  }
  return options;
}

// One file: the report, or a thrown one-line reason (unreadable, not glTF at all).
async function validate(file) {
  let bytes;
  try {
    bytes = new Uint8Array(await readFile(file));
  } catch (e) {
    throw new Error(`${file}: cannot be read (${e.code ?? e.message})`);
  }
  try {
    // maxIssues 0: every issue, so a test log shows all of them.
    return await validator.validateBytes(bytes, { uri: basename(file), maxIssues: 0, writeTimestamp: false });
  } catch (e) {
    throw new Error(`${file}: not a glTF 2.0 asset the validator can read (${e})`);
  }
}

function printReport(file, report, json) {
  if (json) {
    console.log(JSON.stringify(report, null, 2));
    return;
  }
  const i = report.issues;
  console.log(
    `${file}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos, ${i.numHints} hints ` +
      `(gltf-validator ${report.validatorVersion})`,
  );
  for (const m of i.messages) {
    console.log(`  ${SEVERITY[m.severity] ?? m.severity} ${m.code} at ${m.pointer ?? "-"}: ${m.message}`);
  }
}

const options = parseArgs(process.argv.slice(2));
let failed = false;
for (const file of options.files) {
  try {
    const report = await validate(file);
    printReport(file, report, options.json);
    const i = report.issues;
    if (i.numErrors > 0 || (options.strict && i.numWarnings > 0)) failed = true;
  } catch (e) {
    console.error(`validate.mjs: ${e.message}`);
    failed = true;
  }
}
process.exit(failed ? 1 : 0);
