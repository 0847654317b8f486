// study's report (index.html): sortable tables and per-case image viewers. Inlined by study/outputs/html.py.
// Images arrive as RGBE-coded PNGs (study/outputs/viewer.py: mantissas left, shared exponent right, value =
// m * 2^(E - 136); E = 0 & m = 255 is NaN) in data URLs, set by each case's script <fig>/viewer/<case>.js.
"use strict";
(function () {
  // ------------------------------------------------------------------ sortable tables
  function sortBy(th) {
    const table = th.closest("table"), idx = Array.prototype.indexOf.call(th.parentNode.children, th);
    const asc = th.dataset.sort !== "asc";
    table.querySelectorAll("th").forEach(h => { delete h.dataset.sort; });
    th.dataset.sort = asc ? "asc" : "desc";
    const tbody = table.tBodies[0], rows = Array.from(tbody.rows);
    const key = r => {
      const td = r.cells[idx];
      if (!td) return null;
      if (td.dataset.v === undefined) return td.textContent;
      return td.dataset.v === "" ? null : parseFloat(td.dataset.v);
    };
    rows.sort((a, b) => {
      const x = key(a), y = key(b);
      if (x === null || y === null) return (x === null) - (y === null);      // empty cells last, either way
      const c = (typeof x === "number" && typeof y === "number") ? x - y : String(x).localeCompare(String(y));
      return asc ? c : -c;
    });
    rows.forEach(r => tbody.appendChild(r));
  }
  document.querySelectorAll("table.sortable th").forEach(th => th.addEventListener("click", () => sortBy(th)));

  // ------------------------------------------------------------------ the page fits its window
  // The top bar wraps to as many lines as its links need: sticky headers and anchors clear its height (--bar). A
  // table wider than the page scrolls in its own box (its header sticks to the box's top) instead of the page.
  const nav = document.querySelector("nav.toc");
  function fitPage() {
    document.documentElement.style.setProperty("--bar", (nav ? nav.getBoundingClientRect().height : 0) + "px");
    document.querySelectorAll(".tablebox").forEach(box => {
      box.classList.remove("scroll");
      box.classList.toggle("scroll", box.firstElementChild.getBoundingClientRect().width > box.clientWidth + 1);
    });
  }
  fitPage();
  window.addEventListener("resize", fitPage);
  // Folded parts (long tables, a figure's viewers) open on a click, or when a link names them or their heading.
  document.querySelectorAll("details").forEach(d => d.addEventListener("toggle", fitPage));
  function openTarget() {
    const t = location.hash && document.getElementById(decodeURIComponent(location.hash.slice(1)));
    if (!t) return;
    const d = t.closest("details") || (t.nextElementSibling && t.nextElementSibling.tagName === "DETAILS" ?
                                      t.nextElementSibling : null);
    if (d && !d.open) { d.open = true; t.scrollIntoView(); }
  }
  openTarget();
  window.addEventListener("hashchange", openTarget);
  if (nav && "ResizeObserver" in window) new ResizeObserver(fitPage).observe(nav);

  // ------------------------------------------------------------------ viewers
  const MANIFEST = JSON.parse(document.getElementById("study-manifest").textContent);
  const LUTS = JSON.parse(document.getElementById("study-luts").textContent);
  const LAYER_NAMES = {image: "image", angle: "angular error", outcome: "outcome", flip: "FLIP", error: "error",
                       hidden: "hidden"};
  const MIN_SIDE = 280, CONTROLS = 300, GAP = 14;   // px: the smallest canvas; the controls beside a wide one
  const bar = () => { const n = document.querySelector("nav.toc"); return n ? n.getBoundingClientRect().height : 0; };
  const srgb = v => (v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055);
  const loadedScripts = {};

  function loadScript(src) {
    if (!loadedScripts[src]) {
      loadedScripts[src] = new Promise((resolve, reject) => {
        const s = document.createElement("script");
        s.src = src;
        s.onload = resolve;
        s.onerror = () => reject(new Error("cannot load " + src));
        document.head.appendChild(s);
      });
    }
    return loadedScripts[src];
  }

  async function decodePng(url, channels) {
    const b64 = url.slice(url.indexOf(",") + 1), bin = atob(b64), bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    const bmp = await createImageBitmap(new Blob([bytes], {type: "image/png"}),
                                        {premultiplyAlpha: "none", colorSpaceConversion: "none"});
    const c = document.createElement("canvas");
    c.width = bmp.width; c.height = bmp.height;
    const g = c.getContext("2d", {willReadFrequently: true});
    g.drawImage(bmp, 0, 0);
    const px = g.getImageData(0, 0, bmp.width, bmp.height).data, W = bmp.width / 2, H = bmp.height;
    const out = new Float32Array(W * H * channels);
    for (let y = 0; y < H; y++) {
      for (let x = 0; x < W; x++) {
        const i = (y * bmp.width + x) * 4, e = px[(y * bmp.width + W + x) * 4], k = (y * W + x) * channels;
        const f = e > 0 ? Math.pow(2, e - 136) : 0, nan = e === 0 && px[i] === 255;
        for (let ch = 0; ch < channels; ch++) out[k + ch] = nan ? NaN : px[i + ch] * f;
      }
    }
    return {w: W, h: H, channels: channels, data: out};
  }

  const REFS = ["truth_at_hit", "oracle_map", "mitsuba"];
  const REF = "truth_at_hit";                       // what A/B and the difference compare against
  const DIGIT_MS = 900;                             // digits typed within this time form one number (1, 4 → 14)
  const byFig = {};                                 // figure → its viewers: they share exposure and view
  // The exposure slider spans what any image of the page needs (each case's exposure_span: its images' own
  // exposures with a margin, study/outputs/viewer.py), at least ±8 EV.
  const EV_SPAN = Object.values(MANIFEST).flatMap(m => m.cases).reduce(([lo, hi], c) => {
    const ev = typeof c.exposure_ev === "number" ? c.exposure_ev : 0;
    const s = Array.isArray(c.exposure_span) ? c.exposure_span : [ev - 8, ev + 8];
    return [Math.min(lo, s[0], ev), Math.max(hi, s[1], ev)];
  }, [-8, 8]);

  class Viewer {
    constructor(el, fig, c) {
      this.el = el; this.fig = fig; this.c = c;
      this.sources = [...new Set(c.layers.map(l => l.source))];
      this.layerIds = [...new Set(c.layers.map(l => l.layer))];
      const first = this.sources.findIndex(s => !REFS.includes(s));
      this.src = first < 0 ? 0 : first;             // the first method (the references come first)
      this.want = "image"; this.mode = "normal"; this.zoom = null; this.pan = [0, 0];
      this.exposure = typeof c.exposure_ev === "number" ? c.exposure_ev : 0;  // the figure's grid exposure
      this.digits = ""; this.lastDigit = 0;
      this.decoded = new Map();
      (byFig[fig] = byFig[fig] || []).push(this);
      this.build();
    }
    build() {
      const c = this.c, el = this.el;
      el.innerHTML = "";
      const add = (tag, cls, parent) => { const e = document.createElement(tag); if (cls) e.className = cls;
                                         (parent || el).appendChild(e); return e; };
      add("div", "title").textContent = c.title + (c.title !== c.id ? "  (" + c.id + ")" : "");
      const body = add("div", "vbody"), controls = add("div", "controls", body), stage = add("div", "stage", body);
      const srow = add("div", "row sources", controls);
      this.srcButtons = this.sources.map((s, i) => {
        const b = add("button", "", srow);
        b.textContent = (i + 1) + " " + s;
        b.title = "key " + (i + 1) + (i >= 9 ? " (digits typed quickly form one number)" : "");
        b.addEventListener("click", () => { this.src = i; this.show(); });
        return b;
      });
      const lrow = add("div", "row", controls);
      this.layerButtons = this.layerIds.map(l => {
        const b = add("button", "", lrow);
        b.textContent = LAYER_NAMES[l] || l;
        b.addEventListener("click", () => { this.want = l; this.show(); });
        return b;
      });
      const mrow = add("div", "row", controls);
      const mb = (t, title, mode) => { const b = add("button", "mode", mrow); b.textContent = t; b.title = title;
        b.dataset.mode = mode; b.addEventListener("click", () => this.setMode(mode)); return b; };
      this.modeButtons = [mb("a/b ref (r)", "flip to " + REF + " and back (key r)", "flip"),
                          mb("difference (d)", "|image − " + REF + "| (key d)", "diff")];
      const trow = add("div", "row", controls);
      const zb = (t, f) => { const b = add("button", "", trow); b.textContent = t; b.addEventListener("click", f); };
      zb("−", () => this.zoomBy(1 / 1.5)); zb("+", () => this.zoomBy(1.5)); zb("fit", () => this.fit());
      add("span", "", trow).textContent = " exposure";
      this.slider = add("input", "exposure", trow);
      Object.assign(this.slider, {type: "range", min: EV_SPAN[0], max: EV_SPAN[1], step: 0.01,
                                   value: String(this.exposure)});
      this.expLabel = add("span", "", trow);
      this.slider.addEventListener("input", () => this.setExposure(parseFloat(this.slider.value)));
      this.shownLabel = add("div", "shown", controls);
      this.canvas = add("canvas", "view", stage);
      this.legend = add("div", "legend", stage);
      this.readout = add("div", "readout", stage);
      this.links = add("div", "links", controls);
      this.msg = add("div", "msg", controls);
      this.S = 0;
      this.layout();
      if ("ResizeObserver" in window) new ResizeObserver(() => this.layout()).observe(el);
      if (c.missing) this.msg.textContent = "images missing: " + c.script + " (study figure " + this.fig + " writes it)";
      this.bindInput();
      this.updateButtons();
    }
    layout() {                                    // the canvas as large as the row allows, whole in the window
      const cs = getComputedStyle(this.el);
      const w = this.el.clientWidth - parseFloat(cs.paddingLeft) - parseFloat(cs.paddingRight);
      const wide = w >= 2 * CONTROLS + GAP;       // room for the controls beside the image
      this.el.classList.toggle("wide", wide);
      const home = wide ? this.canvas.parentNode.previousSibling : this.canvas.parentNode;  // controls : stage
      if (this.legend.parentNode !== home) { home.append(this.legend, this.readout); }
      const high = Math.max(MIN_SIDE, window.innerHeight - bar() - (wide ? 70 : 200));
      const side = Math.floor(Math.max(MIN_SIDE, Math.min(wide ? w - CONTROLS - GAP : w, high)));
      const S = Math.round(side * (window.devicePixelRatio || 1));
      this.canvas.style.width = this.canvas.style.height = side + "px";
      if (S === this.S) return;
      const keep = this.zoom === null || !this.S ? null : this.view();
      this.S = this.canvas.width = this.canvas.height = S;
      if (keep) this.setView(keep); else if (this.buf) { this.fit(false); this.draw(); }
    }
    siblings() { return (byFig[this.fig] || []).filter(o => o !== this); }
    setExposure(x, share = true) {                // one exposure for every viewer of the figure
      this.exposure = x; this.slider.value = String(x); this.render();
      if (share) this.siblings().forEach(o => o.setExposure(x, false));
    }
    setMode(m) { this.mode = this.mode === m ? "normal" : m; this.show(); }
    bindInput() {
      const cv = this.canvas;
      this.el.addEventListener("keydown", e => this.key(e));
      this.el.addEventListener("focus", () => this.show());
      cv.addEventListener("wheel", e => {
        e.preventDefault();
        const r = cv.getBoundingClientRect();
        this.zoomBy(e.deltaY < 0 ? 1.25 : 0.8, (e.clientX - r.left) * this.S / r.width, (e.clientY - r.top) * this.S / r.height);
      }, {passive: false});
      let drag = null;
      cv.addEventListener("mousedown", e => { drag = [e.clientX, e.clientY, this.pan[0], this.pan[1]]; this.el.focus(); });
      window.addEventListener("mouseup", () => { drag = null; });
      cv.addEventListener("mousemove", e => {
        const r = cv.getBoundingClientRect(), s = this.S / r.width;
        if (drag) {
          this.pan = [drag[2] + (e.clientX - drag[0]) * s, drag[3] + (e.clientY - drag[1]) * s];
          this.draw(); this.shareView();
        }
        this.read((e.clientX - r.left) * s, (e.clientY - r.top) * s);
      });
    }
    pickDigit(d) {                                // 1…9, or two digits typed quickly (10…99); 0 alone: the 10th
      const n = this.sources.length, now = performance.now();
      let s = (now - this.lastDigit < DIGIT_MS ? this.digits : "") + d;
      if (!(parseInt(s, 10) >= 1 && parseInt(s, 10) <= n)) s = d;
      this.digits = s; this.lastDigit = now;
      const k = s === "0" ? 10 : parseInt(s, 10);
      if (k >= 1 && k <= n) this.src = k - 1;
    }
    key(e) {
      const n = this.sources.length, L = this.layerIds.length, li = this.layerIds.indexOf(this.want);
      if (e.ctrlKey || e.metaKey || e.altKey) return;
      if (/^[0-9]$/.test(e.key)) this.pickDigit(e.key);
      else if (e.key === "ArrowRight") this.src = (this.src + 1) % n;
      else if (e.key === "ArrowLeft") this.src = (this.src + n - 1) % n;
      else if (e.key === "ArrowDown") this.want = this.layerIds[(li + 1) % L];
      else if (e.key === "ArrowUp") this.want = this.layerIds[(li + L - 1) % L];
      else if (e.key === "r") { this.setMode("flip"); e.preventDefault(); return; }
      else if (e.key === "d") { this.setMode("diff"); e.preventDefault(); return; }
      else if (e.key === "+" || e.key === "=") { this.zoomBy(1.5); e.preventDefault(); return; }
      else if (e.key === "-") { this.zoomBy(1 / 1.5); e.preventDefault(); return; }
      else if (e.key === "f") { this.fit(); return; }
      else return;
      e.preventDefault();
      this.show();
    }
    find(source, layer) { return this.c.layers.findIndex(l => l.source === source && l.layer === layer); }
    current() {                                   // the wanted layer of this source, else its image
      const s = this.mode === "flip" ? REF : this.sources[this.src], ls = this.c.layers;
      let i = this.find(s, this.mode === "diff" ? "image" : this.want);
      if (i < 0) i = this.find(s, "image");
      return i < 0 ? ls.findIndex(l => l.source === s) : i;
    }
    async urls() {
      if (this.c.missing) throw new Error("images missing: " + this.c.script);
      await loadScript(this.c.script);
      const u = (window.STUDY_VIEWER_DATA || {})[this.c.key];
      if (!u || u.length !== this.c.layers.length) throw new Error("no images for " + this.c.key + " in " + this.c.script);
      return u;
    }
    async decode(i) {
      if (!this.decoded.has(i)) {
        this.decoded.set(i, this.urls().then(u => decodePng(u[i], this.c.layers[i].channels)));
      }
      return this.decoded.get(i);
    }
    async decodeAll() { return Promise.all(this.c.layers.map((_, i) => this.decode(i))); }
    updateButtons() {
      const s = this.sources[this.src];
      this.srcButtons.forEach((b, i) => b.classList.toggle("on", i === this.src));
      this.layerButtons.forEach((b, k) => {
        const l = this.layerIds[k];
        b.classList.toggle("on", l === this.want);
        b.disabled = !this.c.layers.some(x => x.source === s && x.layer === l) && l !== "image";
      });
      this.modeButtons.forEach(b => b.classList.toggle("on", b.dataset.mode === this.mode));
      this.expLabel.textContent = (this.exposure >= 0 ? "+" : "") + this.exposure.toFixed(2) + " EV";
    }
    async show() {
      this.updateButtons();
      const i = this.current(), L = this.c.layers[i], src = this.sources[this.src];
      const what = L.display.title || LAYER_NAMES[L.layer] || L.layer;
      this.shownLabel.textContent =
        this.mode === "diff" ? src + " − " + REF + " — |difference| of the linear radiance" :
        this.mode === "flip" ? REF + " — " + what + "  (a/b against " + src + ": r flips back)" :
        L.source + " — " + what + (L.layer !== this.want ? "  (no " + (LAYER_NAMES[this.want] || this.want) + " for it)" : "");
      this.links.innerHTML = "";
      this.readout.textContent = "";                        // the value under the cursor: of the image shown
      const a = document.createElement(L.have ? "a" : "span");
      a.textContent = L.have ? "EXR: " + L.exr + (L.exr_layer ? " (layer " + L.exr_layer + ")" : "")
                             : "EXR not in this copy (" + L.exr + "; bash scripts/reproduce.sh)";
      if (L.have) a.href = encodeURI(L.exr);
      this.links.appendChild(a);
      const want = [this.mode, i].join();
      try {
        let d = await this.decode(i), disp = L.display;
        if (this.mode === "diff") {
          const r = this.find(REF, "image"), ref = await this.decode(r);
          d = difference(d, ref);
          disp = {type: "hdr", title: "|" + src + " − " + REF + "|"};
        }
        if ([this.mode, this.current()].join() !== want) return;   // switched again meanwhile
        this.shownIndex = i; this.img = d; this.disp = disp;
        if (this.zoom === null) this.fit(false);
        this.render();
      } catch (err) {
        this.msg.textContent = String(err.message || err);
      }
    }
    render() {                                    // the decoded layer → display pixels (crop size) → canvas
      const d = this.img;
      if (!d) return;
      this.updateButtons();
      const disp = this.disp, n = d.w * d.h;
      const px = new Uint8ClampedArray(n * 4), k = Math.pow(2, this.exposure);
      const lut = LUTS[disp.cmap];
      const lo = disp.type === "log" ? Math.log10(disp.lo) : disp.lo, hi = disp.type === "log" ? Math.log10(disp.hi) : disp.hi;
      const cls = (disp.colors || []).map(h => [1, 3, 5].map(j => parseInt(h.slice(j, j + 2), 16)));
      for (let p = 0; p < n; p++) {
        const v = d.data[p * d.channels];
        if (Number.isNaN(v)) { px[p * 4 + 3] = 0; continue; }
        let rgb;
        if (disp.type === "hdr") {
          rgb = [0, 1, 2].map(c => 255 * srgb(Math.min(1, Math.max(0, d.data[p * d.channels + Math.min(c, d.channels - 1)] * k))));
        } else if (disp.type === "classes") {
          rgb = cls[Math.max(0, Math.min(cls.length - 1, Math.round(v)))];
        } else {
          const x = disp.type === "log" ? Math.log10(Math.max(v, 1e-30)) : v;
          rgb = lut[Math.max(0, Math.min(255, Math.round(255 * (x - lo) / (hi - lo))))];
        }
        px[p * 4] = rgb[0]; px[p * 4 + 1] = rgb[1]; px[p * 4 + 2] = rgb[2]; px[p * 4 + 3] = 255;
      }
      this.buf = this.buf && this.buf.width === d.w && this.buf.height === d.h ? this.buf : document.createElement("canvas");
      this.buf.width = d.w; this.buf.height = d.h;
      this.buf.getContext("2d").putImageData(new ImageData(px, d.w, d.h), 0, 0);
      this.legendFor(disp);
      this.draw();
    }
    legendFor(disp) {
      const g = this.legend;
      g.innerHTML = "";
      if (disp.type === "hdr") {
        g.textContent = (this.mode === "diff" ? "|difference|" : "linear radiance") + " × 2^" + this.exposure +
                        ", clipped at 1, sRGB";
        return;
      }
      if (disp.type === "classes") {
        disp.names.forEach((nm, i) => { const s = document.createElement("span"); s.innerHTML = '<span class="sw"></span>';
          s.firstChild.style.background = disp.colors[i]; s.appendChild(document.createTextNode(nm)); g.appendChild(s); });
        return;
      }
      const bar = document.createElement("canvas"), lut = LUTS[disp.cmap];
      bar.width = 256; bar.height = 1;
      const im = new ImageData(256, 1);
      lut.forEach((c, i) => { im.data.set([c[0], c[1], c[2], 255], i * 4); });
      bar.getContext("2d").putImageData(im, 0, 0);
      const t = s => document.createTextNode(s);
      g.append(t(String(disp.lo)), bar, t(String(Number(disp.hi.toPrecision(3))) + " " + (disp.unit || "") +
               (disp.type === "log" ? " (log)" : "")));
    }
    fitZoom() { const [, , h, w] = this.c.crop; return Math.min(this.S / w, this.S / h); }
    fit(redraw = true) {
      const [, , h, w] = this.c.crop;
      this.zoom = this.fitZoom();
      this.pan = [(this.S - w * this.zoom) / 2, (this.S - h * this.zoom) / 2];
      if (redraw) { this.draw(); this.shareView(); }
    }
    zoomBy(f, cx = this.S / 2, cy = this.S / 2) {
      if (this.zoom === null) this.fit(false);
      const z = Math.max(0.25, Math.min(64, this.zoom * f)), r = z / this.zoom;
      this.pan = [cx - (cx - this.pan[0]) * r, cy - (cy - this.pan[1]) * r];
      this.zoom = z;
      this.draw(); this.shareView();
    }
    view() {                                      // zoom relative to fit, and the crop point at the canvas centre
      const [, , h, w] = this.c.crop;
      return {mag: this.zoom / this.fitZoom(), u: (this.S / 2 - this.pan[0]) / this.zoom / w,
              v: (this.S / 2 - this.pan[1]) / this.zoom / h};
    }
    setView(s) {
      const [, , h, w] = this.c.crop;
      this.zoom = this.fitZoom() * s.mag;
      this.pan = [this.S / 2 - s.u * w * this.zoom, this.S / 2 - s.v * h * this.zoom];
      this.draw();
    }
    shareView() { const s = this.view(); this.siblings().forEach(o => o.setView(s)); }
    draw() {
      const g = this.canvas.getContext("2d");
      g.setTransform(1, 0, 0, 1, 0, 0);
      g.clearRect(0, 0, this.S, this.S);
      if (!this.buf) return;
      g.imageSmoothingEnabled = false;
      g.drawImage(this.buf, this.pan[0], this.pan[1], this.buf.width * this.zoom, this.buf.height * this.zoom);
    }
    read(cx, cy) {
      const d = this.img;
      if (!d) return;
      const x = Math.floor((cx - this.pan[0]) / this.zoom), y = Math.floor((cy - this.pan[1]) / this.zoom);
      if (x < 0 || y < 0 || x >= d.w || y >= d.h) { this.readout.textContent = ""; return; }
      const v = Array.from(d.data.slice((y * d.w + x) * d.channels, (y * d.w + x + 1) * d.channels));
      const disp = this.disp;
      const txt = Number.isNaN(v[0]) ? "–" : disp.type === "classes" ? disp.names[Math.round(v[0])] :
        v.map(a => a.toPrecision(4)).join(" ") + (disp.unit ? " " + disp.unit : "");
      this.readout.textContent = "pixel (" + (x + this.c.crop[1]) + ", " + (y + this.c.crop[0]) + "): " + txt;
    }
    valueAt(i, x, y) {                            // for tests: decoded value of layer i at crop pixel (x, y)
      return this.decode(i).then(d => Array.from(d.data.slice((y * d.w + x) * d.channels, (y * d.w + x + 1) * d.channels)));
    }
  }

  function difference(a, b) {                     // |a − b| per channel (NaN where either is)
    const out = new Float32Array(a.w * a.h * 3);
    for (let p = 0; p < a.w * a.h; p++) {
      for (let c = 0; c < 3; c++) {
        out[p * 3 + c] = Math.abs(a.data[p * a.channels + Math.min(c, a.channels - 1)] -
                                  b.data[p * b.channels + Math.min(c, b.channels - 1)]);
      }
    }
    return {w: a.w, h: a.h, channels: 3, data: out};
  }

  const viewers = [];
  document.querySelectorAll(".viewer").forEach(el => {
    const fig = el.dataset.fig, c = MANIFEST[fig].cases[parseInt(el.dataset.case, 10)];
    const v = new Viewer(el, fig, c);
    viewers.push(v);
    el.addEventListener("mousedown", () => { viewers.forEach(o => o.el.classList.toggle("active", o === v)); });
  });
  window.addEventListener("resize", () => viewers.forEach(v => v.layout()));  // the window's height, too
  if ("IntersectionObserver" in window) {
    const io = new IntersectionObserver(es => es.forEach(e => {
      if (e.isIntersecting) { io.unobserve(e.target); viewers.find(v => v.el === e.target).show(); }
    }), {rootMargin: "300px"});
    viewers.forEach(v => io.observe(v.el));
  } else {
    viewers.forEach(v => v.show());
  }
  window.studyViewers = viewers;
  // For tests and for checking a copy of the report: decode every image of every viewer; lists what failed.
  window.studyCheckViewers = async () => {
    const res = {viewers: viewers.length, layers: 0, failed: []};
    for (const v of viewers) {
      for (let i = 0; i < v.c.layers.length; i++) {
        try { const d = await v.decode(i); if (d.w > 0 && d.h > 0) res.layers++; else res.failed.push(v.c.key + " #" + i); }
        catch (err) { res.failed.push(v.c.key + " #" + i + ": " + (err.message || err)); }
      }
    }
    return res;
  };
})();
