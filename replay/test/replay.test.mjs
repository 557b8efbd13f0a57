// Opens a replay.html in headless Chromium (Debian's /usr/bin/chromium, WebGL through
// SwiftShader) and checks that it draws: the canvas is not blank, the robot is drawn
// differently at two times given as `#t=<seconds>`, and every event of the run has its mark on
// the time slider and its line in the side panel.
// Usage: node test/replay.test.mjs <replay.html> <t1> <t2> [screenshot directory]
import { chromium } from 'playwright-core';
import { mkdirSync } from 'node:fs';
import { resolve } from 'node:path';
import { pathToFileURL } from 'node:url';

const [page_file, t1, t2, shots = 'out/replay-test'] = process.argv.slice(2);
if (!page_file || t1 === undefined || t2 === undefined) {
  console.error('usage: node test/replay.test.mjs <replay.html> <t1> <t2> [screenshot directory]');
  process.exit(2);
}
const BROWSER_FLAGS = ['--headless', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'];
// A rendered scene has at least this share of pixels not of its most common colour.
const MIN_DRAWN_SHARE = 0.05;
// Two times differ if at least this share of pixels changed.
const MIN_CHANGED_SHARE = 0.002;

// Reads the WebGL canvas (the renderer keeps its drawing buffer) in the page and returns the
// share of pixels not of its most common colour (0 for a blank canvas) and the share that
// changed since the previous call.
const measureCanvas = (page) => page.evaluate(() => {
  const source = document.querySelector('#view canvas');
  const copy = document.createElement('canvas');
  copy.width = source.width;
  copy.height = source.height;
  const context = copy.getContext('2d');
  context.drawImage(source, 0, 0);
  const pixels = context.getImageData(0, 0, copy.width, copy.height).data;
  const previous = window.previousPixels ?? pixels;
  const differs = (a, i, b, j) => Math.abs(a[i] - b[j]) + Math.abs(a[i + 1] - b[j + 1]) + Math.abs(a[i + 2] - b[j + 2]) > 24;
  const histogram = new Map();
  let changed = 0;
  for (let i = 0; i < pixels.length; i += 4) {
    const colour = ((pixels[i] >> 3) << 10) | ((pixels[i + 1] >> 3) << 5) | (pixels[i + 2] >> 3);
    histogram.set(colour, (histogram.get(colour) ?? 0) + 1);
    if (differs(pixels, i, previous, i)) changed += 1;
  }
  window.previousPixels = pixels;
  const count = pixels.length / 4;
  return { drawn: 1 - Math.max(...histogram.values()) / count, changed: changed / count };
});

async function showAt(page, t) {
  await page.evaluate((time) => { window.location.hash = `#t=${time}`; }, t);
  await page.waitForFunction((time) => Math.abs(window.replayShownTime - time) < 1e-6, Number(t));
  // Two more animation frames so the frame of that time is on the canvas.
  await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
}

mkdirSync(shots, { recursive: true });
const browser = await chromium.launch({ executablePath: '/usr/bin/chromium', args: BROWSER_FLAGS });
let failed = false;
try {
  const page = await browser.newPage({ viewport: { width: 1000, height: 600 } });
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  await page.goto(`${pathToFileURL(resolve(page_file)).href}#t=${t1}`);
  const measured = [];
  for (const t of [t1, t2]) {
    await showAt(page, t);
    await page.screenshot({ path: `${shots}/replay_t${t}.png` });
    measured.push(await measureCanvas(page));
  }
  const story = await page.evaluate(() => ({
    events: JSON.parse(document.getElementById('replay-data').textContent).events.length,
    marks: document.querySelectorAll('#marks .mark').length,
    lines: document.querySelectorAll('#story a').length,
  }));
  const drawn = measured.map((m) => m.drawn);
  const changed = measured[1].changed;
  console.log(`drawn share at t=${t1}: ${drawn[0].toFixed(3)}, at t=${t2}: ${drawn[1].toFixed(3)} (> ${MIN_DRAWN_SHARE})`);
  console.log(`pixels changed between the two times: ${changed.toFixed(4)} (> ${MIN_CHANGED_SHARE})`);
  console.log(`events: ${story.events}, marks on the slider: ${story.marks}, lines in the panel: ${story.lines}`);
  console.log(`screenshots in ${shots}`);
  if (errors.length > 0) { console.error(`page errors: ${errors.join('; ')}`); failed = true; }
  if (drawn.some((share) => share < MIN_DRAWN_SHARE)) { console.error('the replay is blank'); failed = true; }
  if (story.marks !== story.events || story.lines !== story.events) { console.error('an event has no mark or line'); failed = true; }
  if (changed < MIN_CHANGED_SHARE) { console.error('the robot is drawn the same at both times'); failed = true; }
} finally {
  await browser.close();
}
process.exit(failed ? 1 : 0);
