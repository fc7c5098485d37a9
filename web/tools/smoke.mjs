// End-to-end smoke check of a running gateway with headless chromium:
//   node tools/smoke.mjs URL [screenshot.png] [seconds]
// Opens URL, waits for the first frame, prints window.phasecast and the
// console, saves a screenshot. Not part of `npm test` (needs a server).
import { chromium } from 'playwright-core';

export const CHROMIUM_ARGS = ['--no-sandbox', '--disable-gpu', '--enable-unsafe-swiftshader', '--use-angle=swiftshader',
  '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'];

const [url, shot = '/tmp/phasecast.png', seconds = '3'] = process.argv.slice(2);
if (!url) {
  console.error('usage: node tools/smoke.mjs http://127.0.0.1:8080/?size=640x480 [screenshot.png] [seconds]');
  process.exit(2);
}
const browser = await chromium.launch({ executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium', args: CHROMIUM_ARGS });
try {
  const page = await browser.newPage({ viewport: { width: 1000, height: 640 } });
  page.on('console', (m) => console.log(`console.${m.type()}: ${m.text()}`));
  page.on('pageerror', (e) => console.log(`pageerror: ${e.message}`));
  await page.goto(url);
  await page.waitForFunction(() => window.phasecast?.ready || window.phasecast?.lastError, null, { timeout: 30000 });
  await page.waitForTimeout(1000 * Number(seconds));
  console.log(JSON.stringify(await page.evaluate(() => window.phasecast), null, 1));
  console.log(await page.evaluate(() => document.getElementById('hud').textContent));
  await page.screenshot({ path: shot });
  console.log(`screenshot: ${shot}`);
} finally {
  await browser.close();
}
