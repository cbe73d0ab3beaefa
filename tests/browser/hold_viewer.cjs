#!/usr/bin/env node
// Keeps the viewer page open in headless Chromium with a query typed, for
// measuring what an open page costs a training process:
//
//   node tests/browser/hold_viewer.cjs --url http://127.0.0.1:PORT/ --class NAME --seconds N
//
// The page polls the server on its own (summary every 2 s, points and the
// query again on every new field). Prints how many field versions it saw.
'use strict';

const { chromium } = require('playwright-core');

const args = {};
for (let i = 2; i + 1 < process.argv.length; i += 2) {
  args[process.argv[i].replace(/^--/, '')] = process.argv[i + 1];
}

(async () => {
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    headless: true,
    args: ['--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
  const page = await browser.newPage({ viewport: { width: 1000, height: 700 } });
  await page.goto(args.url);
  await page.waitForFunction(() => window.viewerState && window.viewerState.ready, null, { timeout: 120000 });
  await page.fill('#query-text', args.class);
  await page.press('#query-text', 'Enter');
  console.log('hold_viewer: page ready, query typed');
  const end = Date.now() + 1000 * Number(args.seconds);
  const seen = new Set();
  while (Date.now() < end) {
    const v = await page.evaluate(() => window.viewerState.fieldVersion).catch(() => null);
    if (v === null) break;
    if (!seen.has(v)) console.log(`hold_viewer: field version ${v}`);
    seen.add(v);
    await new Promise((r) => setTimeout(r, 1000));
  }
  console.log(`hold_viewer: page open, field versions seen: ${[...seen].join(', ')}`);
  await browser.close();
})().catch((e) => {
  console.error(`hold_viewer: ${e.message}`);
  process.exit(1);
});
