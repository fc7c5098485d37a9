// Builds the page: node build.mjs [--out DIR] (default dist).
// 1. proto/phasecast.proto -> src/generated/phasecast.json (protobufjs descriptor,
//    imported by src/protocol.js through main.js; protobufjs/light at run time).
// 2. src/main.js -> DIR/app.js (esbuild, minified, with a source map).
// 3. index.html and style.css -> DIR.
import { build } from 'esbuild';
import { mkdirSync, writeFileSync, copyFileSync } from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { loadDescriptor } from './tools/descriptor.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));

function outDir(argv) {
  const i = argv.indexOf('--out');
  if (i < 0) return path.join(here, 'dist');
  const dir = argv[i + 1];
  if (!dir || dir.startsWith('--')) throw new Error('--out needs a directory (e.g. --out ../build/web)');
  return path.resolve(dir);
}

function writeDescriptor() {
  const file = path.join(here, 'src', 'generated', 'phasecast.json');
  mkdirSync(path.dirname(file), { recursive: true });
  writeFileSync(file, JSON.stringify(loadDescriptor()) + '\n');
  return file;
}

async function bundle(out) {
  const result = await build({
    entryPoints: [path.join(here, 'src', 'main.js')],
    outfile: path.join(out, 'app.js'),
    bundle: true,
    minify: true,
    sourcemap: true,
    format: 'esm',
    target: ['es2020'],
    platform: 'browser',
    metafile: true,
    logLevel: 'warning',
  });
  return result.metafile.outputs;
}

async function main() {
  const out = outDir(process.argv.slice(2));
  mkdirSync(out, { recursive: true });
  writeDescriptor();
  const outputs = await bundle(out);
  for (const file of ['index.html', 'style.css']) copyFileSync(path.join(here, file), path.join(out, file));
  const app = Object.entries(outputs).find(([name]) => name.endsWith('app.js'));
  console.log(`phasecast-web: wrote ${out} (app.js ${app ? app[1].bytes : '?'} bytes)`);
}

main().catch((e) => {
  console.error(`phasecast-web build: ${e.message}`);
  process.exit(1);
});
