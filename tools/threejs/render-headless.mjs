// Renders an export with view.html in headless Chromium and writes the canvas as a PNG.
//
//   node render-headless.mjs MODEL.glb OUT.png [WIDTH HEIGHT [QUERY]]
//
// Serves, on 127.0.0.1 (a free port), view.html from this folder, node_modules/ (three) and the
// model's folder under /model/, opens view.html?file=model/NAME with puppeteer-core in the
// Chromium at $CHROME (default /usr/bin/chromium, software WebGL through SwiftShader), waits
// until the page's title is 'done', and writes the canvas's PNG data URL to OUT.png and the
// page's report (what GLTFLoader built) to OUT.json. QUERY is appended to the page's URL
// (e.g. `mipmaps=0`, see view.html).
//
// node_modules (three, puppeteer-core) is this folder's own (`npm install` here), or the one
// named by $THREEJS_NODE_MODULES.

import http from 'node:http';
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const modulesDir = path.resolve(process.env.THREEJS_NODE_MODULES || path.join(here, 'node_modules'));
const require = createRequire(path.join(path.dirname(modulesDir), 'render-headless.cjs'));
const puppeteer = require('puppeteer-core');

const [model, out, w = '512', h = '512', extra = ''] = process.argv.slice(2);
if (!model || !out) {
  console.error('usage: node render-headless.mjs MODEL.glb OUT.png [WIDTH HEIGHT [QUERY]]');
  process.exit(2);
}
const modelDir = path.dirname(path.resolve(model));
const modelName = path.basename(model);
const width = parseInt(w, 10);
const height = parseInt(h, 10);

const types = { '.html': 'text/html', '.js': 'text/javascript', '.mjs': 'text/javascript',
  '.glb': 'model/gltf-binary', '.gltf': 'model/gltf+json', '.bin': 'application/octet-stream',
  '.png': 'image/png', '.json': 'application/json' };

// Maps a URL path to a file inside one of the three served roots, or null.
function resolve(urlPath) {
  const p = decodeURIComponent(urlPath.split('?')[0]);
  const under = (root, rest) => {
    const f = path.resolve(root, '.' + path.posix.normalize('/' + rest));
    return f.startsWith(root + path.sep) ? f : null;
  };
  if (p === '/view.html') return path.join(here, 'view.html');
  if (p.startsWith('/node_modules/')) return under(modulesDir, p.slice('/node_modules'.length));
  if (p.startsWith('/model/')) return under(modelDir, p.slice('/model'.length));
  return null;
}

const server = http.createServer((req, res) => {
  const f = resolve(req.url);
  if (!f || !fs.existsSync(f) || !fs.statSync(f).isFile()) {
    res.writeHead(404).end();
    return;
  }
  res.writeHead(200, { 'Content-Type': types[path.extname(f)] || 'application/octet-stream' });
  fs.createReadStream(f).pipe(res);
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const port = server.address().port;

const browser = await puppeteer.launch({
  executablePath: process.env.CHROME || '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    `--window-size=${width},${height}`],
});
let code = 0;
try {
  const page = await browser.newPage();
  await page.setViewport({ width, height, deviceScaleFactor: 1 });
  page.on('console', (m) => console.error(`[console.${m.type()}] ${m.text()}`));
  page.on('pageerror', (e) => console.error(`[page error] ${e.message}`));
  const url = `http://127.0.0.1:${port}/view.html?file=model/${encodeURIComponent(modelName)}&w=${width}&h=${height}${extra ? '&' + extra : ''}`;
  await page.goto(url);
  await page.waitForFunction(() => document.title === 'done' || document.title === 'error',
    { timeout: 120000 });
  const info = JSON.parse(await page.$eval('#info', (e) => e.textContent));
  fs.writeFileSync(out.replace(/\.png$/i, '') + '.json', JSON.stringify(info, null, 1) + '\n');
  if (info.error) {
    console.error(info.error);
    code = 1;
  } else {
    const dataUrl = await page.$eval('#png', (e) => e.textContent);
    fs.writeFileSync(out, Buffer.from(dataUrl.replace(/^data:image\/png;base64,/, ''), 'base64'));
    console.log(`wrote ${out} (${width}x${height}, three r${info.three}, ${info.glRenderer})`);
  }
} finally {
  await browser.close();
  server.close();
}
process.exit(code);
