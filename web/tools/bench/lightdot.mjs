// Measures where to light-dot the transfer (README.md, "Light-dot"):
//   node tools/bench/lightdot.mjs
// in headless chromium (SwiftShader, as the browser tests run).
import { build } from 'esbuild';
import { chromium } from 'playwright-core';
import { fileURLToPath } from 'node:url';

const entry = fileURLToPath(new URL('./lightdot-page.js', import.meta.url));
const bundle = await build({ entryPoints: [entry], bundle: true, write: false, format: 'iife', logLevel: 'warning' });
const browser = await chromium.launch({ executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--no-first-run'] });
const page = await browser.newPage();
page.on('pageerror', (e) => console.log(`pageerror: ${e.message}`));
await page.setContent('<canvas id="c" width="640" height="480"></canvas>');
await page.addScriptTag({ content: bundle.outputFiles[0].text });
for (const side of [36, 100, 200]) {
  const r = await page.evaluate((o) => window.bench(o), { side, rank_u: 11, rank_a: 15, count: 30 });
  console.log(JSON.stringify(r));
}
await browser.close();
