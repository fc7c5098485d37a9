// Measures many instances in one view (README.md, "Many instances"):
//   node tools/bench/instances.mjs [side]
// 1, 16 and 64 instances of a side x side synthetic grid (default 60: 3 600
// points, as the demo cloth) at 1280x720, in headless chromium (SwiftShader,
// as the browser tests run).
import { openBenchPage } from './page.mjs';

const side = Number(process.argv[2] ?? 60);
const { browser, page } = await openBenchPage('instances-page.js', { width: 1280, height: 720 });
for (const instances of [1, 16, 64]) {
  const r = await page.evaluate((o) => window.bench(o), { side, rank_u: 12, rank_a: 7, count: 20, instances });
  console.log(JSON.stringify(r));
}
await browser.close();
