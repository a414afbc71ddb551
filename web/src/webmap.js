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
    tileRetries: 0 };
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
  base['elevation (hillshade)'].addTo(map);
  overlays.traversability.addTo(map);
  L.control.layers(base, overlays, { collapsed: false }).addTo(map);
  L.control.scale({ imperial: false }).addTo(map);
  if (info.bounds) {
    const b = info.bounds;
    map.fitBounds([[b[1], b[0]], [b[3], b[2]]]);
  } else {
    map.setView([0, 0], 0);
  }

  const showStatus = (state) => {
    status.textContent = 'map version ' + hook.version + ' \u00b7 ' + state;
  };
  const visible = () => Object.values(hook.layers).filter((l) => map.hasLayer(l));
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
    showStatus('live');
  });
  events.onerror = () => showStatus('reconnecting...');

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
      value.textContent = p[k] === null ? 'unknown' : String(p[k]);
      tr.append(name, value);
      return tr;
    }));
    panel.hidden = false;
    hook.lastPoint = answer;
  });
})();
