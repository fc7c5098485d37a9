// Measures where to light-dot the transfer (README.md, "Light-dot"):
//   node tools/bench/lightdot.mjs
// in headless chromium (SwiftShader, as the browser tests run).
import { openBenchPage } from './page.mjs';

const { browser, page } = await openBenchPage('lightdot-page.js', { width: 640, height: 480 });
for (const side of [36, 100, 200]) {
  const r = await page.evaluate((o) => window.bench(o), { side, rank_u: 11, rank_a: 15, count: 30 });
  console.log(JSON.stringify(r));
}
await browser.close();
