// The live web map of bgkmapd (docs/webmap.md): server-rendered tiles over map-local metres,
// refreshed when /events says which part of the map changed; a click shows the cell's values
// from /points. Everything comes from the server that serves this page.
(async function () {
  'use strict';
  const status = document.getElementById('status');
  if (typeof L === 'undefined') {
    status.textContent = 'Leaflet is missing from this build: run scripts/install-deps.sh and rebuild bgkmapd';
    return;
  }
  // A busy server answers 503 with Retry-After: ask again, a few times, as it says.
  const fetchRetrying = async (url) => {
    for (let attempt = 0; ; attempt++) {
      const reply = await fetch(url);
      if (reply.status !== 503 || attempt >= 5) return reply;
      const after = Number(reply.headers.get('Retry-After')) || 1;
      await new Promise((resolve) => setTimeout(resolve, 1000 * Math.min(after, 5)));
    }
  };
  // The view in the address (docs/webmap.md): ?x=&y=&z= (metres, zoom), &layer= (a base layer),
  // &still: no live stream, and data-ready="true" on <html> once the tiles and the fleet are drawn,
  // so a headless browser can take the picture.
  const params = new URLSearchParams(window.location.search);
  const still = params.has('still');
  const info = await (await fetchRetrying('/map.json')).json();
  const res = info.resolution;
  // Map-local metres, y up (Leaflet's lat = y, lng = x); zoom 0 draws one map cell per pixel.
  const crs = L.extend({}, L.CRS.Simple, {
    transformation: new L.Transformation(1 / res, 0, -1 / res, 0),
  });
  const map = L.map('map', {
    crs, minZoom: info.min_zoom, maxZoom: info.max_zoom, zoomSnap: 1, attributionControl: false,
  });
  const hook = { map, info, events: 0, version: info.map_version, lastPoint: null, layers: {},
    tileRetries: 0, robots: [], ready: false, still };
  window.bgkmap = hook;  // for the browser test and the curious

  // A tile layer that can reload the tiles meeting a box of metres.
  const LiveTiles = L.TileLayer.extend({
    // A busy server answers 503 with Retry-After (docs/webmap.md); a tile that failed is asked for
    // again a few times, backing off, before Leaflet is told it failed.
    createTile(coords, done) {
      let attempt = 0;
      const key = this._tileCoordsToKey(coords);
      const tile = L.TileLayer.prototype.createTile.call(this, coords, (err, el) => {
        if (!err || attempt >= 5) {
          done(err, el);
          return;
        }
        attempt += 1;
        hook.tileRetries += 1;
        const url = this.getTileUrl(coords);
        setTimeout(() => {
          const live = this._tiles[key];
          if (live && live.el === el) el.src = url + (url.includes('?') ? '&' : '?') + 'retry=' + attempt;
        }, 250 * 2 ** (attempt - 1));
      });
      return tile;
    },
    refreshBox(box, version) {
      for (const key in this._tiles) {
        const tile = this._tiles[key];
        const b = this._tileCoordsToBounds(tile.coords);
        if (b.getWest() < box[2] && b.getEast() > box[0] && b.getSouth() < box[3] && b.getNorth() > box[1]) {
          this.reload(tile, version);
        }
      }
    },
    refreshAll(version) {
      for (const key in this._tiles) this.reload(this._tiles[key], version);
    },
    reload(tile, version, attempt = 0) {
      // Swapped in once loaded: the old picture stays until the new one is there. A refused
      // reload is retried like a first load, unless a newer version has been asked for since.
      tile.wanted = version;
      const url = this.getTileUrl(tile.coords) + '?v=' + version;
      const img = new Image();
      img.onload = () => { if (tile.wanted === version) tile.el.src = url; };
      img.onerror = () => {
        if (attempt >= 5 || tile.wanted !== version) return;
        hook.tileRetries += 1;
        setTimeout(() => {
          if (tile.wanted === version && this._tiles[this._tileCoordsToKey(tile.coords)] === tile) {
            this.reload(tile, version, attempt + 1);
          }
        }, 250 * 2 ** attempt);
      };
      img.src = url;
    },
  });
  const layer = (name, options) => {
    const l = new LiveTiles('/tiles/' + name + '/{z}/{x}/{y}.png',
      Object.assign({
        tileSize: info.tile_pixels, minZoom: info.min_zoom, maxZoom: info.max_zoom, noWrap: true, keepBuffer: 1,
      }, options));
    hook.layers[name] = l;
    return l;
  };
  const base = {
    'elevation (hillshade)': layer('elevation', {}),
    'elevation variance': layer('elevation_variance', {}),
    'traversability variance': layer('traversability_variance', {}),
    'disagreement': layer('disagreement', {}),
  };
  // What a planner gets: the state, and why a cell is blocked (webmap.md has the colours).
  const overlays = {
    traversability: layer('traversability', { opacity: 0.55 }),
    state: layer('state', { opacity: 0.55 }),
    'why blocked': layer('block_reason', { opacity: 0.7 }),
  };
  const baseByName = { elevation: 'elevation (hillshade)', elevation_variance: 'elevation variance',
    traversability_variance: 'traversability variance' };
  const firstBase = base[baseByName[params.get('layer')] || 'elevation (hillshade)'];
  firstBase.addTo(map);
  overlays.traversability.addTo(map);
  L.control.layers(base, overlays, { collapsed: false }).addTo(map);
  L.control.scale({ imperial: false }).addTo(map);
  // A view set while the fleet loads (by a script, say) is kept: the first view does not jump it.
  let viewSetMeanwhile = false;
  map.whenReady(() => { viewSetMeanwhile = true; });
  const fleet = await loadFleet();
  const view = ['x', 'y', 'z'].map((k) => Number(params.get(k)));
  if (viewSetMeanwhile) {
    // kept
  } else if (params.has('x') && params.has('y') && view.every(Number.isFinite)) {
    map.setView([view[1], view[0]], params.has('z') ? view[2] : 0, { animate: false });
  } else {
    map.fitBounds(firstView(fleet), { animate: false });
  }
  addLegend(map, firstBase === base['elevation (hillshade)'] ? 'elevation' : params.get('layer'));
  addCursor(map);
  // The address follows the view, so a link (or a reload) shows the same place.
  map.on('moveend zoomend baselayerchange', () => {
    const c = map.getCenter();
    const q = new URLSearchParams(window.location.search);
    q.set('x', c.lng.toFixed(1));
    q.set('y', c.lat.toFixed(1));
    q.set('z', String(map.getZoom()));
    window.history.replaceState(null, '', '?' + q.toString().replace(/still=(&|$)/, 'still$1'));
  });

  const showStatus = (state) => {
    status.textContent = 'map version ' + hook.version + ' \u00b7 ' + state;
  };
  const visible = () => Object.values(hook.layers).filter((l) => map.hasLayer(l));
  if (still) {
    // A picture: every visible layer's tiles loaded, then the flag a headless browser waits for.
    showStatus('still');
    await Promise.all(visible().map((l) => new Promise((resolve) => {
      if (!l.isLoading()) resolve(); else l.once('load', resolve);
    })));
    hook.ready = true;
    document.documentElement.dataset.ready = 'true';
  } else {
    followEvents();
  }
  function followEvents() {
    const events = new EventSource('/events');
    let connectedBefore = false;
    events.addEventListener('hello', (e) => {
      const d = JSON.parse(e.data);
      // Changes between the page's first tiles (or a lost connection) and now: reload everything.
      if (connectedBefore || d.map_version !== hook.version) visible().forEach((l) => l.refreshAll(d.map_version));
      connectedBefore = true;
      hook.version = d.map_version;
      showStatus('live');
    });
    events.addEventListener('tiles', (e) => {
      const d = JSON.parse(e.data);
      hook.version = d.map_version;
      hook.events += 1;
      for (const l of visible()) d.tiles.forEach((box) => l.refreshBox(box, d.map_version));
      loadFleet();  // a scan moved its robot
      showStatus('live');
    });
    events.onerror = () => showStatus('reconnecting...');
  }

  // A click: the cell's values, as `bgkmap points x,y` prints them.
  const panel = document.getElementById('cell');
  const marker = L.circleMarker([0, 0], { radius: 5, color: '#fff', weight: 2, fillOpacity: 0 });
  map.on('click', async (e) => {
    const x = e.latlng.lng, y = e.latlng.lat;
    const reply = await fetchRetrying('/points?x=' + x + '&y=' + y);
    if (!reply.ok) {
      document.getElementById('cell-where').textContent = 'error: ' + (await reply.text());
      panel.hidden = false;
      return;
    }
    const answer = await reply.json();
    const p = answer.points[0];
    marker.setLatLng(e.latlng).addTo(map);
    document.getElementById('cell-where').textContent =
      'x ' + p.x.toFixed(2) + ' m, y ' + p.y.toFixed(2) + ' m (version ' + answer.map_version + ')';
    const rows = ['elevation', 'elevation_variance', 'traversability', 'traversability_variance', 'state',
      'disagreement', 'block_reason'];
    const table = document.getElementById('cell-values');
    table.replaceChildren(...rows.map((k) => {
      const tr = document.createElement('tr');
      tr.dataset.layer = k;
      const name = document.createElement('td');
      name.textContent = k;
      const value = document.createElement('td');
      value.textContent = formatValue(k, p[k]);
      value.dataset.value = p[k] === null ? 'unknown' : String(p[k]);  // exact, as /points
      tr.append(name, value);
      return tr;
    }));
    panel.hidden = false;
    hook.lastPoint = answer;
  });

  // The fleet: each robot's recent trajectory and an arrow at its latest pose, pointing along its
  // heading (/robots.json, from the server's robot registry).
  async function loadFleet() {
    const reply = await fetchRetrying('/robots.json');
    if (!reply.ok) return hook.robots;
    const robots = (await reply.json()).robots;
    hook.fleetLayer = hook.fleetLayer || L.layerGroup().addTo(map);
    hook.fleetLayer.clearLayers();
    robots.forEach((r, i) => {
      if (!r.pose) return;
      const color = robotColor(i);
      L.polyline(r.trail.map(([x, y]) => [y, x]), { color, weight: 3, opacity: 0.9, interactive: false })
        .addTo(hook.fleetLayer);
      const deg = -r.pose.yaw * 180 / Math.PI;  // screen rotation is clockwise, yaw counter-clockwise
      const icon = L.divIcon({
        className: 'robot-marker',
        iconSize: [28, 28],
        html: `<svg width="28" height="28" viewBox="-14 -14 28 28" style="transform: rotate(${deg}deg)">` +
          `<polygon points="12,0 -8,-8 -4,0 -8,8" fill="${color}" stroke="#fff" stroke-width="1.5"/></svg>`,
      });
      L.marker([r.pose.y, r.pose.x], { icon, keyboard: false })
        .bindTooltip(r.id, { permanent: true, direction: 'right', offset: [12, 0], className: 'robot-label' })
        .addTo(hook.fleetLayer);
    });
    hook.robots = robots;
    return robots;
  }

  function robotColor(i) {
    return ['#ff2bd6', '#2bd9ff', '#ffd21f', '#ffffff', '#8a5cff'][i % 5];
  }

  // The first view: where the robots went (their trajectories, 30 m around), within the known
  // cells; else the known cells; else the origin. Stray far returns then do not shrink the map.
  function firstView(robots) {
    const b = info.bounds;
    const known = b ? L.latLngBounds([[b[1], b[0]], [b[3], b[2]]]) : L.latLngBounds([[-20, -20], [20, 20]]);
    const points = robots.flatMap((r) => r.trail.map(([x, y]) => [y, x]));
    if (points.length === 0) return known;
    const trail = L.latLngBounds(points);
    const margin = 30;
    const around = L.latLngBounds(
      [trail.getSouth() - margin, trail.getWest() - margin],
      [trail.getNorth() + margin, trail.getEast() + margin]);
    if (!b || !known.intersects(around)) return around;
    return L.latLngBounds(
      [Math.max(around.getSouth(), known.getSouth()), Math.max(around.getWest(), known.getWest())],
      [Math.min(around.getNorth(), known.getNorth()), Math.min(around.getEast(), known.getEast())]);
  }

  // A legend for the overlay (traversability) and the base layer shown.
  function addLegend(m, baseName) {
    const legend = L.control({ position: 'topleft' });
    const ramps = {
      traversability: ['traversability', 'linear-gradient(90deg, #1a9641, #ffffbf, #d7191c)',
        '0 flat', '1 not traversable'],
      elevation: ['elevation: hillshade, light from the north-west', 'linear-gradient(90deg, #222, #eee)',
        'shade', 'light'],
      variance: ['standard deviation', 'linear-gradient(90deg, #08306b, #00e5ff, #ffffff)', '0', '0.5'],
    };
    const row = ([title, gradient, lo, hi]) =>
      `<div class="legend-title">${title}</div><div class="legend-ramp" style="background:${gradient}"></div>` +
      `<div class="legend-ends"><span>${lo}</span><span>${hi}</span></div>`;
    legend.onAdd = () => {
      const div = L.DomUtil.create('div', 'panel legend');
      div.id = 'legend';
      const draw = (name) => {
        const baseRamp = name === 'elevation' ? ramps.elevation : ramps.variance;
        div.innerHTML = row(ramps.traversability) + row(baseRamp) +
          '<div class="legend-title">robots: arrow = heading, line = recent path</div>';
      };
      draw(baseName || 'elevation');
      m.on('baselayerchange', (e) => draw(e.name.startsWith('elevation (') ? 'elevation' : 'variance'));
      return div;
    };
    legend.addTo(m);
  }

  // The coordinates under the cursor: the map frame's, and with a georeference (map.json) the
  // CRS's easting and northing (origin + offset, axes aligned, docs/webmap.md), with latitude and
  // longitude for a WGS 84 / UTM CRS (EPSG:326zz north, 327zz south).
  function addCursor(m) {
    const geo = info.georeference;
    const utm = geo ? utmZone(geo.crs) : null;
    const cursor = L.control({ position: 'topright' });
    cursor.onAdd = () => {
      const div = L.DomUtil.create('div', 'panel cursor');
      div.id = 'cursor';
      const local = L.DomUtil.create('div', '', div);
      local.id = 'cursor-map';
      local.textContent = 'x, y (map frame, m)';
      const projected = geo ? L.DomUtil.create('div', '', div) : null;
      const geographic = utm ? L.DomUtil.create('div', '', div) : null;
      if (projected) {
        projected.id = 'cursor-crs';
        projected.textContent = 'E, N (' + crsLabel(geo.crs) + ', m)';
      }
      if (geographic) {
        geographic.id = 'cursor-latlon';
        geographic.textContent = 'latitude, longitude (WGS 84)';
      }
      m.on('mousemove', (e) => {
        const x = e.latlng.lng, y = e.latlng.lat;
        local.textContent = 'x ' + x.toFixed(2) + ' m, y ' + y.toFixed(2) + ' m';
        if (!projected) return;
        const east = geo.origin[0] + x, north = geo.origin[1] + y;
        projected.textContent = 'E ' + east.toFixed(2) + ' m, N ' + north.toFixed(2) + ' m (' + crsLabel(geo.crs) + ')';
        if (!geographic) return;
        const [lat, lon] = utmToLatLon(east, north, utm);
        geographic.textContent = Math.abs(lat).toFixed(7) + '\u00b0 ' + (lat < 0 ? 'S' : 'N') + ', ' +
          Math.abs(lon).toFixed(7) + '\u00b0 ' + (lon < 0 ? 'W' : 'E');
      });
      return div;
    };
    cursor.addTo(m);
  }

  // "EPSG:32610" as it is; a WKT by its name; anything else shortened.
  function crsLabel(text) {
    const named = /^\s*[A-Z_]+\["([^"]+)"/.exec(text);
    if (named) return named[1];
    return text.length <= 24 ? text : text.slice(0, 21) + '...';
  }

  // The UTM zone of an "EPSG:326zz" (north) or "EPSG:327zz" (south) CRS, else null.
  function utmZone(text) {
    const m = /^\s*EPSG:32([67])(\d\d)\s*$/i.exec(text);
    if (!m || Number(m[2]) < 1 || Number(m[2]) > 60) return null;
    return { zone: Number(m[2]), south: m[1] === '7' };
  }

  // UTM to WGS 84 latitude and longitude in degrees: the inverse transverse Mercator of Kruger's
  // series to n^3 (Karney, "Transverse Mercator with an accuracy of a few nanometers", 2011,
  // eqs. 11-15): about a millimetre within a zone.
  function utmToLatLon(east, north, { zone, south }) {
    const a = 6378137, f = 1 / 298.257223563, k0 = 0.9996;
    const n = f / (2 - f), n2 = n * n, n3 = n2 * n;
    const A = a / (1 + n) * (1 + n2 / 4 + n2 * n2 / 64);
    const beta = [n / 2 - 2 * n2 / 3 + 37 * n3 / 96, n2 / 48 + n3 / 15, 17 * n3 / 480];
    const delta = [2 * n - 2 * n2 / 3 - 2 * n3, 7 * n2 / 3 - 8 * n3 / 5, 56 * n3 / 15];
    const xi = (north - (south ? 10000000 : 0)) / (k0 * A), eta = (east - 500000) / (k0 * A);
    let xi1 = xi, eta1 = eta;
    for (let j = 1; j <= 3; j++) {
      xi1 -= beta[j - 1] * Math.sin(2 * j * xi) * Math.cosh(2 * j * eta);
      eta1 -= beta[j - 1] * Math.cos(2 * j * xi) * Math.sinh(2 * j * eta);
    }
    const chi = Math.asin(Math.sin(xi1) / Math.cosh(eta1));
    let phi = chi;
    for (let j = 1; j <= 3; j++) phi += delta[j - 1] * Math.sin(2 * j * chi);
    const lambda0 = (zone * 6 - 183) * Math.PI / 180;
    const lambda = lambda0 + Math.atan2(Math.sinh(eta1), Math.cos(xi1));
    return [phi * 180 / Math.PI, lambda * 180 / Math.PI];
  }

  // A value as a person reads it: a few digits and its unit.
  function formatValue(k, v) {
    if (v === null) return 'unknown';
    switch (k) {
      case 'elevation': return v.toFixed(2) + ' m';
      case 'elevation_variance': return v.toPrecision(2) + ' m\u00b2 (\u03c3 ' + Math.sqrt(v).toFixed(3) + ' m)';
      case 'traversability': return v.toFixed(3) + ' (0 flat, 1 not traversable)';
      case 'traversability_variance': return v.toPrecision(2);
      case 'state': return ['unknown', 'traversable', 'not traversable'][v] || String(v);
      default: return String(v);
    }
  }
})();
