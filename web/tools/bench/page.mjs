// Opens a benchmark's browser side (a script of this folder, bundled) on a
// canvas of the given size in headless chromium with SwiftShader, as the
// browser tests run; returns { browser, page }.
import { build } from 'esbuild';
import { chromium } from 'playwright-core';
import { fileURLToPath } from 'node:url';

export async function openBenchPage(script, { width, height }) {
  const entry = fileURLToPath(new URL(`./${script}`, import.meta.url));
  const bundle = await build({ entryPoints: [entry], bundle: true, write: false, format: 'iife', logLevel: 'warning' });
  const browser = await chromium.launch({ executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
    args: ['--no-sandbox', '--disable-gpu', '--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--no-first-run'] });
  const page = await browser.newPage();
  page.on('pageerror', (e) => console.log(`pageerror: ${e.message}`));
  await page.setContent(`<canvas id="c" width="${width}" height="${height}"></canvas>`);
  await page.addScriptTag({ content: bundle.outputFiles[0].text });
  return { browser, page };
}
