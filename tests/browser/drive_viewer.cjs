#!/usr/bin/env node
// Drives the viewer page in headless Chromium and writes what it saw to DIR/result.json.
//
//   node tests/browser/drive_viewer.cjs --url http://127.0.0.1:PORT/ --out DIR --class NAME \
//        [--chromium /usr/bin/chromium]
//
// playwright-core is resolved through NODE_PATH. Exit status: 0 whenever result.json was
// written (the calling test asserts on its contents); non-zero only when playwright-core
// or Chromium cannot be started, with the reason on stderr.
'use strict';

const fs = require('fs');
const path = require('path');

function parseArgs(argv) {
  const args = { chromium: process.env.CHROMIUM || '/usr/bin/chromium' };
  for (let i = 0; i < argv.length; i++) {
    const m = /^--(url|out|class|chromium)$/.exec(argv[i]);
    if (!m || i + 1 >= argv.length) {
      console.error(`drive_viewer: unexpected argument ${argv[i]}`);
      process.exit(2);
    }
    args[m[1]] = argv[++i];
  }
  for (const k of ['url', 'out', 'class']) {
    if (!args[k]) {
      console.error(`drive_viewer: --${k} is required`);
      process.exit(2);
    }
  }
  return args;
}

// WebGL2 in headless Chromium without a GPU runs on ANGLE's SwiftShader (software Vulkan).
// --enable-unsafe-swiftshader keeps Chromium from refusing or warning about that fallback;
// the others keep the browser from reaching the network or doing background work.
const CHROMIUM_ARGS = ['--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--disable-quic', '--no-first-run', '--disable-background-networking', '--disable-component-update', '--disable-sync'];

// Error text without terminal colour codes and trailing blank lines.
const clean = (e) => String(e && e.message ? e.message : e).replace(/\u001b\[[0-9;]*m/g, '').trim();

// Resolves after the page has painted two more animation frames.
const twoFrames = (page) => page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));

// Waits until viewerState[counter] exceeds `before`, or a new error shows in the page.
async function waitForCounter(page, counter, timeout) {
  const before = await page.evaluate((c) => ({ n: window.viewerState[c], errors: window.viewerState.errors || 0 }), counter);
  return async () => {
    await page.waitForFunction(([c, b]) => {
      const s = window.viewerState;
      return s[c] > b.n || (s.errors || 0) > b.errors;
    }, [counter, before], { timeout, polling: 100 });
    const s = await page.evaluate(() => window.viewerState);
    if (!(s[counter] > before.n)) throw new Error(`the viewer reported an error: ${s.lastError}`);
  };
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  fs.mkdirSync(args.out, { recursive: true });

  let chromium;
  try {
    ({ chromium } = require('playwright-core'));
  } catch (e) {
    console.error(`drive_viewer: cannot load playwright-core (set NODE_PATH): ${e.message}`);
    process.exit(3);
  }
  let browser;
  try {
    browser = await chromium.launch({ executablePath: args.chromium, headless: true, args: CHROMIUM_ARGS });
  } catch (e) {
    console.error(`drive_viewer: cannot start Chromium at ${args.chromium}: ${e.message}`);
    process.exit(4);
  }

  const result = {
    console_errors: [], page_errors: [], legend: [], query_ok: false, render_ok: false,
    render_width: 0, depth_caption: '', opacity_width: 0, points: 0, steps: [],
  };
  const page = await browser.newPage({ viewport: { width: 1000, height: 700 } });
  page.on('console', (msg) => { if (msg.type() === 'error') result.console_errors.push(msg.text()); });
  page.on('pageerror', (err) => result.page_errors.push(String(err && err.stack ? err.stack : err)));

  let ready = false;
  // Runs one step; a failure is recorded and the later steps still run when they can.
  const step = async (name, fn) => {
    const started = Date.now();
    try {
      if (name !== 'load' && !ready) throw new Error('skipped: the viewer never became ready');
      await fn();
      result.steps.push({ step: name, ok: true, error: null, seconds: (Date.now() - started) / 1000 });
      return true;
    } catch (e) {
      // The page's own status line usually says why (e.g. a server error).
      const shown = await page.evaluate(() => window.viewerState && window.viewerState.lastError).catch(() => null);
      const msg = clean(e);
      const error = shown && !msg.includes(shown) ? `${msg} (viewer status: ${shown})` : msg;
      result.steps.push({ step: name, ok: false, error, seconds: (Date.now() - started) / 1000 });
      return false;
    }
  };

  await step('load', async () => {
    await page.goto(args.url, { waitUntil: 'load', timeout: 60000 });
    await page.waitForFunction(() => window.viewerState && window.viewerState.ready, null, { timeout: 60000, polling: 100 });
    ready = true;
    await twoFrames(page);
    result.points = await page.evaluate(() => window.viewerState.points);
    await page.locator('#view').screenshot({ path: path.join(args.out, 'initial.png') });
  });

  await step('legend', async () => {
    result.legend = await page.$$eval('#legend .legend-item', (items) => items.map((el) => {
      const name = el.querySelector('.legend-name');
      return (name || el).textContent.trim();
    }));
    if (result.legend.length === 0) throw new Error('the legend has no items');
  });

  result.query_ok = await step('query', async () => {
    const done = await waitForCounter(page, 'queryDone', 60000);
    await page.fill('#query-text', args.class);
    await page.press('#query-text', 'Enter');
    await done();
    await twoFrames(page);
    await page.locator('#view').screenshot({ path: path.join(args.out, 'query.png') });
  });

  result.render_ok = await step('render', async () => {
    const done = await waitForCounter(page, 'renderDone', 120000);
    await page.click('#render-go');
    await done();
    result.render_width = await page.$eval('#render-rgb', (img) => img.naturalWidth);
    if (!(result.render_width > 0)) throw new Error('#render-rgb has no image');
    // The depth image's scale under it, and the opacity beside it.
    result.depth_caption = await page.$eval('#render-depth-caption', (c) => c.textContent);
    result.opacity_width = await page.$eval('#render-opacity', (img) => img.naturalWidth);
    await twoFrames(page);
    await page.screenshot({ path: path.join(args.out, 'page.png'), fullPage: true });
  });

  result.last_error = ready ? await page.evaluate(() => window.viewerState.lastError).catch(() => null) : null;
  fs.writeFileSync(path.join(args.out, 'result.json'), JSON.stringify(result, null, 2) + '\n');
  await browser.close().catch(() => {});
  const failed = result.steps.filter((s) => !s.ok).map((s) => `${s.step}: ${s.error}`);
  console.log(`drive_viewer: ${result.steps.length - failed.length} of ${result.steps.length} steps ok` +
    (failed.length ? `; ${failed.join('; ')}` : '') +
    `; ${result.console_errors.length} console errors, ${result.page_errors.length} page errors`);
  process.exit(0);
}

main().catch((e) => {
  console.error(`drive_viewer: ${e && e.stack ? e.stack : e}`);
  process.exit(5);
});
