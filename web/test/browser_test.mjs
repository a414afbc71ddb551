// The live web map in a real browser (docs/webmap.md): Debian's chromium, headless, driven with
// playwright-core, against the real bgkmapd with the real street scans. Checks that
//   1. the page draws map pixels (screenshot analysis), fetching nothing but loopback;
//   2. a scan inserted afterwards appears on the page within 2 s (Server-Sent Events);
//   3. a click shows the values `bgkmap points` prints for the clicked point (rounded, with units;
//      exact in the cell's data-value);
//   4. the still view (?still&x=&y=&z=): no live stream, a ready flag once drawn, and in its
//      picture the KITTI car's marker and trajectory drawn where the car was; the cursor box
//      shows the map frame's x, y, the CRS's easting and northing (the server is georeferenced)
//      and the latitude and longitude gdaltransform gives for them.
// With BGKMAP_WEB_AUTH=1 the same over HTTPS with tokens (a certificate made by the openssl CLI):
// the page is 401 before /login?token=, and everything above works with the cookie it sets.
// Exit 0 pass, 1 fail, 77 skip (chromium missing). Environment: BGKMAPD, BGKMAP_CLI,
// BGKMAP_SHARED_DATA, CHROMIUM (default /usr/bin/chromium), BGKMAP_WEB_AUTH.
import { spawn, execFileSync } from 'node:child_process';
import crypto from 'node:crypto';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { decodePng } from './png.mjs';

const chromiumPath = process.env.CHROMIUM || '/usr/bin/chromium';
if (!fs.existsSync(chromiumPath)) {
  console.log(`SKIP: ${chromiumPath} not found; scripts/install-deps.sh installs Debian's chromium`);
  process.exit(77);
}
const { chromium } = await import('playwright-core');
const bgkmapd = process.env.BGKMAPD;
const cli = process.env.BGKMAP_CLI;
const street = path.join(process.env.BGKMAP_SHARED_DATA, 'ouster_os1_128_street');
// Sanitizer builds run everything several times slower (scripts/sanitize.sh): the 2 s bound
// scales with their CTest timeouts.
const scale = Number(process.env.BGKMAP_TEST_TIMEOUT_SCALE || 1);
// A generous deadline, not a latency bound: CI's 2 shared cores may be loaded (the latency is
// logged; docs/webmap.md gives the measured figure).
const appearLimit = 30.0 * scale;
const t0 = Date.now();
const log = (...args) => console.log(`[${((Date.now() - t0) / 1000).toFixed(2)} s]`, ...args);
let failures = 0;
const check = (ok, what) => {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  if (!ok) failures += 1;
};

const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'bgkmap_browser_'));
// A KITTI-like directory holding some of the street scans, each pose moved by `dx` metres in x.
function scanDir(name, indices, dx, source = street) {
  const dir = path.join(tmp, name);
  fs.mkdirSync(path.join(dir, 'velodyne'), { recursive: true });
  const poses = fs.readFileSync(path.join(source, 'poses.txt'), 'utf8').trim().split('\n');
  const lines = indices.map((i, k) => {
    fs.symlinkSync(path.join(source, 'velodyne', String(i).padStart(6, '0') + '.bin'),
      path.join(dir, 'velodyne', String(k).padStart(6, '0') + '.bin'));
    const v = poses[i].trim().split(/\s+/).map(Number);
    v[3] += dx;
    return v.join(' ');
  });
  fs.writeFileSync(path.join(dir, 'poses.txt'), lines.join('\n') + '\n');
  return dir;
}

// With auth: a self-signed certificate for 127.0.0.1, an admin token (the CLI inserts with it;
// any role's token opens the page).
const auth = process.env.BGKMAP_WEB_AUTH === '1';
const token = crypto.randomBytes(16).toString('hex');
// The map frame georeferenced in WGS 84 / UTM zone 10N: the cursor box shows the CRS's easting
// and northing and the latitude and longitude beside the map frame's x, y.
const origin = [551000.5, 4180000.25, 12.5];
const serverArgs = ['--listen', '127.0.0.1:0', '--http', '127.0.0.1:0',
  '--set', 'georeference.crs=EPSG:32610', '--set', `georeference.origin=[${origin.join(', ')}]`];
// Without auth, two queries at once: the page's first tiles meet the limit (503, Retry-After)
// and must still all load, retried by the page. (Mutation: without LiveTiles.createTile's retry,
// tiles stay broken and the first wait times out, as it did in CI under load.)
if (!auth) serverArgs.push('--set', 'server.max_concurrent_queries=2');
const cliAuth = [];
if (auth) {
  const cert = path.join(tmp, 'server.pem'), key = path.join(tmp, 'server.key');
  execFileSync('openssl', ['req', '-x509', '-newkey', 'rsa:2048', '-nodes', '-keyout', key,
    '-out', cert, '-days', '1', '-subj', '/CN=127.0.0.1', '-addext',
    'subjectAltName=IP:127.0.0.1'], { stdio: 'pipe' });
  const tokens = path.join(tmp, 'tokens.yaml');
  const digest = crypto.createHash('sha256').update(token).digest('hex');
  fs.writeFileSync(tokens, `tokens:\n  - {name: ops, sha256: ${digest}, role: admin}\n`);
  fs.writeFileSync(path.join(tmp, 'token'), token);
  serverArgs.push('--set', `server.tls.cert_file=${cert}`, '--set', `server.tls.key_file=${key}`,
    '--set', `server.auth.tokens_file=${tokens}`);
  cliAuth.push('--tls-ca', cert, '--token-file', path.join(tmp, 'token'));
}

// bgkmapd on loopback ports chosen by the system, read from its log.
const server = spawn(bgkmapd, serverArgs, { stdio: ['ignore', 'pipe', 'pipe'] });
// However this script ends (a broken stdout pipe, say), bgkmapd does not outlive it.
process.on('exit', () => { if (server.exitCode === null) server.kill('SIGKILL'); });
let serverLog = '';
const ports = await new Promise((resolve, reject) => {
  const timer = setTimeout(() => reject(new Error('bgkmapd did not start:\n' + serverLog)), 20000);
  const onData = (chunk) => {
    serverLog += chunk;
    const grpc = /event=listening .*port=(\d+)/.exec(serverLog);
    const http = /event=metrics_listening .*port=(\d+)/.exec(serverLog);
    if (grpc && http) {
      clearTimeout(timer);
      resolve({ grpc: `127.0.0.1:${grpc[1]}`, http: Number(http[1]) });
    }
  };
  server.stdout.on('data', onData);
  server.stderr.on('data', onData);
  server.on('exit', (code) => reject(new Error(`bgkmapd exited ${code}:\n${serverLog}`)));
});
const insert = (dir, robot) =>
  execFileSync(cli, ['insert', dir, '--server', ports.grpc, '--robot', robot, ...cliAuth],
    { stdio: 'pipe' });

// The still view of the KITTI car's drive (every other scan, 300 m west of the street): the page
// opened at the car's trajectory with ?still, its ready flag awaited, and its screenshot checked
// for the car's arrow at its last pose and its trajectory's line at its first, in the car's colour,
// and not 15 m beside the drive (mutation: markers drawn at (x, y) swapped, or the trail left out).
async function stillView(context, base, livePage) {
  const kitti = path.join(process.env.BGKMAP_SHARED_DATA, 'kitti_raw_0048');
  insert(scanDir('car', [0, 3, 6, 9, 12, 15, 18, 21], -300, kitti), 'car');
  const fleet = await livePage.evaluate(() => fetch('/robots.json').then((r) => r.json())).catch(() => null);
  const car = fleet && fleet.robots.find((r) => r.id === 'car');
  check(car && car.trail.length === 8 && car.pose, `/robots.json has the car's 8 poses (${car && car.trail.length})`);
  if (!car) return;
  const [x0, y0] = car.trail[0];
  const cx = (x0 + car.pose.x) / 2, cy = (y0 + car.pose.y) / 2;
  const page = await context.newPage();
  const opened = `${base}/?still&x=${cx.toFixed(1)}&y=${cy.toFixed(1)}&z=0`;
  await page.goto(opened, { waitUntil: 'load' });
  await page.waitForFunction(() => document.documentElement.dataset.ready === 'true', null, { timeout: 15000 });
  await page.waitForTimeout(300);  // Leaflet fades tiles in
  const png = await page.screenshot();
  fs.writeFileSync('webmap-still.png', png);
  const shot = decodePng(png);
  const index = await page.evaluate(() => window.bgkmap.robots.findIndex((r) => r.id === 'car'));
  const color = await page.evaluate((i) => ['#ff2bd6', '#2bd9ff', '#ffd21f', '#ffffff', '#8a5cff'][i % 5], index);
  const rgb = [1, 3, 5].map((i) => parseInt(color.slice(i, i + 2), 16));
  const near = async (x, y, radius) => {
    const at = await page.evaluate(([lat, lng]) => window.bgkmap.map.latLngToContainerPoint([lat, lng]), [y, x]);
    let n = 0;
    for (let dy = -radius; dy <= radius; dy++) {
      for (let dx = -radius; dx <= radius; dx++) {
        const px = Math.round(at.x) + dx, py = Math.round(at.y) + dy;
        if (px < 0 || py < 0 || px >= shot.width || py >= shot.height) continue;
        const i = (py * shot.width + px) * 4;
        const d = Math.abs(shot.rgba[i] - rgb[0]) + Math.abs(shot.rgba[i + 1] - rgb[1]) + Math.abs(shot.rgba[i + 2] - rgb[2]);
        if (d < 60) n += 1;
      }
    }
    return n;
  };
  const atPose = await near(car.pose.x, car.pose.y, 6);
  const atStart = await near(x0, y0, 3);
  // 15 m beside the drive's middle, across its direction.
  const len = Math.hypot(car.pose.x - x0, car.pose.y - y0) || 1;
  const sideX = cx - 15 * (car.pose.y - y0) / len, sideY = cy + 15 * (car.pose.x - x0) / len;
  const beside = await near(sideX, sideY, 6);
  log(`still view: ${atPose} marker pixels at the last pose, ${atStart} trail pixels at the first, ${beside} beside`);
  check(atPose >= 20, `the car's arrow is drawn at its last pose (${atPose} pixels of ${color})`);
  check(atStart >= 3, `the car's trajectory is drawn through its first pose (${atStart} pixels)`);
  check(beside === 0, `nothing of the car 15 m beside its drive (${beside} pixels)`);
  const status = await page.evaluate(() => document.getElementById('status').textContent);
  check(status.includes('still'), `the status says still (${status})`);
  const streamed = await page.evaluate(() =>
    performance.getEntriesByType('resource').some((e) => e.name.includes('/events')));
  check(!streamed, 'the still view opens no event stream');
  const url = new URL(page.url());
  check(url.searchParams.has('still') && url.searchParams.get('z') === '0',
    `the address keeps the view (${url.search})`);
  const legend = await page.evaluate(() => document.getElementById('legend').textContent);
  check(legend.includes('traversability') && legend.includes('robots'), `a legend (${legend.slice(0, 60)}...)`);
  await page.mouse.move(shot.width / 2, shot.height / 2);
  const cursor = await page.evaluate(() => ['cursor-map', 'cursor-crs', 'cursor-latlon']
    .map((id) => (document.getElementById(id) || { textContent: '' }).textContent));
  const xy = /^x (-?[\d.]+) m, y (-?[\d.]+) m$/.exec(cursor[0]);
  check(xy && Math.abs(Number(xy[1]) - cx) < 1 && Math.abs(Number(xy[2]) - cy) < 1,
    `the cursor's map coordinates at the view's centre (${cursor[0]})`);
  // The CRS's coordinates are the origin plus the map frame's (mutation: x and y swapped, or the
  // origin left out, is off by metres), the latitude and longitude GDAL's for them.
  const en = /^E (-?[\d.]+) m, N (-?[\d.]+) m \(EPSG:32610\)$/.exec(cursor[1]);
  check(en && xy && Math.abs(Number(en[1]) - origin[0] - Number(xy[1])) < 0.011 &&
    Math.abs(Number(en[2]) - origin[1] - Number(xy[2])) < 0.011,
  `the cursor's CRS coordinates: origin + map frame (${cursor[1]})`);
  const ll = /^([\d.]+)\u00b0 N, ([\d.]+)\u00b0 W$/.exec(cursor[2]);
  if (en) {
    const [lon, lat] = execFileSync('gdaltransform', ['-s_srs', 'EPSG:32610', '-t_srs', 'EPSG:4326',
      '-output_xy'], { input: `${en[1]} ${en[2]}\n`, encoding: 'utf8' }).trim().split(/\s+/).map(Number);
    // 1e-6 degrees: 0.1 m; the page shows 7 decimals.
    check(ll && Math.abs(Number(ll[1]) - lat) < 1e-6 && Math.abs(-Number(ll[2]) - lon) < 1e-6,
      `the cursor's latitude and longitude (${cursor[2]}; gdaltransform ${lat}, ${lon})`);
  }
  const mapJson = await page.evaluate(() => fetch('/map.json').then((r) => r.json()));
  check(mapJson.georeference && mapJson.georeference.crs === 'EPSG:32610' &&
    mapJson.georeference.origin.join() === origin.join(), `/map.json has the georeference (${JSON.stringify(mapJson.georeference)})`);
  await page.close();
}

let context;
try {
  insert(scanDir('first', [0, 1], 0), 'street');
  log('bgkmapd up, two street scans inserted');
  const userData = path.join(tmp, 'chromium-profile');  // fresh
  context = await chromium.launchPersistentContext(userData, {
    executablePath: chromiumPath,
    headless: true,
    ignoreHTTPSErrors: auth,  // the test's own self-signed certificate
    viewport: { width: 1280, height: 800 },
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
  const page = context.pages()[0] || await context.newPage();
  const offsite = [];
  await page.route('**/*', (route) => {
    const url = new URL(route.request().url());
    if (url.hostname === '127.0.0.1') return route.continue();
    offsite.push(url.href);
    return route.abort();
  });
  const pageErrors = [];
  page.on('pageerror', (e) => pageErrors.push(String(e)));
  const base = `${auth ? 'https' : 'http'}://127.0.0.1:${ports.http}`;
  if (auth) {
    const refused = await page.goto(base + '/', { waitUntil: 'load' });
    check(refused.status() === 401, `the page without a token is 401 (${refused.status()})`);
    const wrong = await page.goto(base + '/login?token=wrong', { waitUntil: 'load' });
    check(wrong.status() === 401, `/login with a wrong token is 401 (${wrong.status()})`);
    await page.goto(base + '/login?token=' + token, { waitUntil: 'load' });
    check(page.url() === base + '/', `/login redirects to the page (${page.url()})`);
    const cookies = await context.cookies(base);
    const c = cookies.find((k) => k.name === 'bgkmap_token');
    check(c && c.httpOnly && c.secure && c.sameSite === 'Strict',
      `the cookie is HttpOnly, Secure, SameSite=Strict (${JSON.stringify(c)})`);
    check(!(await page.evaluate(() => document.cookie)).includes('bgkmap_token'),
      'the page\'s script cannot read the token');
  } else {
    await page.goto(base + '/', { waitUntil: 'load' });
  }
  // The page sets its own first view before it goes live: the test's view comes after it.
  await page.waitForFunction(() => window.bgkmap && window.bgkmap.map &&
    document.getElementById('status').textContent.includes('live'), null, { timeout: 10000 });
  // The whole street and empty land east of it: 0.4 m per pixel.
  await page.evaluate(() => window.bgkmap.map.setView([10, 60], -2, { animate: false }));
  const tilesSettled = () => page.waitForFunction(() => {
    const tiles = [...document.querySelectorAll('img.leaflet-tile')];
    return tiles.length > 0 && tiles.every((t) => t.complete && t.classList.contains('leaflet-tile-loaded'));
  }, null, { timeout: 10000 });
  await tilesSettled().catch(async (e) => {
    const states = await page.evaluate(() => [...document.querySelectorAll('img.leaflet-tile')]
      .map((t) => `${t.src} complete=${t.complete} class=${t.className}`).join('\n') +
      ` zoom ${window.bgkmap.map.getZoom()} panes ${document.querySelector('.leaflet-tile-pane').innerHTML.slice(0, 300)}`);
    throw new Error(`${e.message}\n${states}\n${pageErrors.join('\n')}`);
  });
  const retries = await page.evaluate(() => window.bgkmap.tileRetries);
  log(`every tile loaded, ${retries} asked for again after a 503`);
  if (!auth) check(retries > 0, `with two queries at once some tiles were refused and retried (${retries})`);
  await page.waitForFunction(() => document.getElementById('status').textContent.includes('live'),
    null, { timeout: 10000 });
  await page.waitForTimeout(400);  // Leaflet fades tiles in

  // Pixels that are not the map's background (#1b1f24), away from the controls.
  const drawn = async (file) => {
    const png = await page.screenshot();
    if (file) fs.writeFileSync(file, png);  // left in the test's directory to look at
    const shot = decodePng(png);
    let n = 0;
    for (let y = 20; y < shot.height - 60; y++) {
      for (let x = 60; x < shot.width - 280; x++) {
        const i = (y * shot.width + x) * 4;
        const d = Math.abs(shot.rgba[i] - 0x1b) + Math.abs(shot.rgba[i + 1] - 0x1f) +
          Math.abs(shot.rgba[i + 2] - 0x24);
        if (d > 30) n += 1;
      }
    }
    return n;
  };
  const before = await drawn('webmap-before.png');
  log(`page drawn: ${before} map pixels`);
  check(before > 8000, `the page draws the street map (${before} pixels > 8000)`);

  // A scan appears: the last street scan, 150 m east, where the map was empty.
  const eventsBefore = await page.evaluate(() => window.bgkmap.events);
  insert(scanDir('shifted', [2], 150), 'east');
  const inserted = Date.now();
  let after = before, seconds = 0;
  while (Date.now() - inserted < 2000 * appearLimit) {
    after = await drawn();
    seconds = (Date.now() - inserted) / 1000;
    if (after > before + 5000) break;
    await page.waitForTimeout(50);
  }
  await drawn('webmap-after.png');
  const events = await page.evaluate(() => window.bgkmap.events);
  const view = await page.evaluate(() => {
    const m = window.bgkmap.map;
    return `zoom ${m.getZoom()}, centre x ${m.getCenter().lng.toFixed(1)} y ${m.getCenter().lat.toFixed(1)}`;
  });
  log(`after the insert: ${after} map pixels at ${seconds.toFixed(2)} s, ${events - eventsBefore} events, ${view}`);
  check(after > before + 5000,
    `an inserted scan appears, live (after ${seconds.toFixed(2)} s, deadline ${appearLimit} s; +${after - before} pixels)`);
  check(events > eventsBefore, 'the page was told by /events');

  // A click shows the values `bgkmap points` prints.
  const at = await page.evaluate(() => window.bgkmap.map.latLngToContainerPoint([0.3, 8.2]));
  await page.mouse.click(at.x, at.y);
  await page.waitForFunction(() => window.bgkmap.lastPoint !== null, null, { timeout: 5000 });
  const shown = await page.evaluate(() => window.bgkmap.lastPoint);
  const p = shown.points[0];
  const printed = JSON.parse(execFileSync(cli,
    ['points', '--server', ports.grpc, `${p.x},${p.y}`, ...cliAuth], { encoding: 'utf8' }));
  const q = printed.points[0];
  const layers = ['elevation', 'elevation_variance', 'traversability', 'traversability_variance', 'state',
    'disagreement', 'block_reason'];
  log(`clicked x ${p.x} y ${p.y}:`, JSON.stringify(p));
  check(q.x === p.x && q.y === p.y, 'the CLI was asked about the clicked point');
  check(printed.map_version === shown.map_version, 'same map version');
  check(p.elevation !== null && p.traversability !== null, 'the clicked cell is known');
  for (const k of layers) check(p[k] === q[k], `${k}: page ${p[k]}, bgkmap points ${q[k]}`);
  const table = await page.evaluate(() => Object.fromEntries(
    [...document.querySelectorAll('#cell-values tr')].map((tr) => [tr.dataset.layer,
      [tr.cells[1].textContent, tr.cells[1].dataset.value]])));
  for (const k of layers) {
    check(table[k][1] === (q[k] === null ? 'unknown' : String(q[k])),
      `the panel holds ${k} = ${table[k][1]} exactly and shows "${table[k][0]}"`);
  }
  check(table.elevation[0] === q.elevation.toFixed(2) + ' m', `elevation rounded with its unit (${table.elevation[0]})`);
  check(['traversable', 'not traversable'].includes(table.state[0]), `state in words (${table.state[0]})`);

  await stillView(context, base, page);
  check(offsite.length === 0, `nothing fetched beyond loopback (${offsite.join(', ') || 'none'})`);
  check(pageErrors.length === 0, `no script errors (${pageErrors.join('; ') || 'none'})`);
} catch (e) {
  console.log('FAIL', e.stack || e);
  failures += 1;
} finally {
  if (context) await context.close();
  server.kill('SIGTERM');
  await new Promise((resolve) => server.exitCode !== null ? resolve() : server.on('exit', resolve));
  fs.rmSync(tmp, { recursive: true, force: true });
}
log(failures === 0 ? 'PASS' : `${failures} check(s) failed`);
process.exit(failures === 0 ? 0 : 1);
