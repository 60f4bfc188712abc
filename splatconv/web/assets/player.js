// splatconv's WebGL2 player for .splatv and .splatvq scenes: plain JavaScript, no build step,
// no external requests. The page that embeds this script (built by
// splatconv/web/page.py) also carries the shader sources splatconv/render runs,
// the sort worker's and the .splatvq decode worker's sources and a JSON
// configuration naming the scene segments.
"use strict";
(() => {
  const MAGIC = 0x674b;
  const TEXWIDTH = 4096;
  const SPLATS_PER_ROW = 1024;
  const RECORD_BYTES = 64;
  const ZNEAR = 0.2, ZFAR = 200.0;
  const SECONDS_PER_SEGMENT = 4; // the clip plays this long per segment at 1x speed
  const QUAD = new Float32Array([-2, -2, 2, -2, 2, 2, -2, 2]);

  const $ = (id) => document.getElementById(id);
  const embedded = (name) => document.querySelector(`script[data-asset="${name}"]`).textContent;
  const config = JSON.parse(embedded("config"));

  // ---------------------------------------------------------------- camera maths
  // Column-major 4x4 lists, summed in the order splatconv/render/camera.py uses,
  // so the sort sees the very numbers the headless renderer's sort sees.

  function projectionMatrix(fx, fy, width, height) {
    return [
      (2 * fx) / width, 0, 0, 0,
      0, -(2 * fy) / height, 0, 0,
      0, 0, ZFAR / (ZFAR - ZNEAR), 1,
      0, 0, -(ZFAR * ZNEAR) / (ZFAR - ZNEAR), 0,
    ];
  }

  function cameraView(camera) {
    const r = camera.rotation.flat().map(Number);
    const t = camera.position.map(Number);
    return [
      r[0], r[1], r[2], 0,
      r[3], r[4], r[5], 0,
      r[6], r[7], r[8], 0,
      -t[0] * r[0] - t[1] * r[3] - t[2] * r[6],
      -t[0] * r[1] - t[1] * r[4] - t[2] * r[7],
      -t[0] * r[2] - t[1] * r[5] - t[2] * r[8],
      1,
    ];
  }

  function multiply(a, b) {
    const out = [];
    for (let col = 0; col < 4; col++) {
      for (let row = 0; row < 4; row++) {
        out.push(b[4 * col] * a[row] + b[4 * col + 1] * a[4 + row]
                 + b[4 * col + 2] * a[8 + row] + b[4 * col + 3] * a[12 + row]);
      }
    }
    return out;
  }

  // Camera-space moves are applied on the left of the view matrix: M * view.
  function translation(x, y, z) {
    return [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, y, z, 1];
  }

  function rotation(angle, axis) {
    const c = Math.cos(angle), s = Math.sin(angle);
    if (axis === "x") return [1, 0, 0, 0, 0, c, s, 0, 0, -s, c, 0, 0, 0, 0, 1];
    if (axis === "y") return [c, 0, -s, 0, 0, 1, 0, 0, s, 0, c, 0, 0, 0, 0, 1];
    return [c, s, 0, 0, -s, c, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
  }

  // ---------------------------------------------------------------- state

  const canvas = $("canvas");
  const state = {
    view: null,         // column-major world -> camera matrix (doubles)
    fx: 1000, fy: 1000, // the file's camera focal lengths, kept at any window size (unless fitting)
    cameraWidth: 0, cameraHeight: 0, // that camera's size, which fitting scales the focal lengths by
    fit: !!config.fit,  // fit the camera's whole view to the window (render --fit), else splaTV's way
    pivot: 4,           // distance to the point orbiting turns about, along the view axis
    cameras: [],
    time: 0,            // clip time over [0, 1] (all segments)
    playing: true,
    speed: 1,
    mode: "loop",       // "loop" or "pingpong"
    direction: 1,
    segments: [],
    error: null,
    frames: 0,
    frameMs: 0,
    lastFrame: 0,
    drawnKey: null,     // what the last frame showed, for tests: see status()
    version: 0,         // bumped when what a frame would draw changes (a sort arrived, new files)
    lastDrawKey: null,
    drewLast: false,
    firstMegabyteAt: null,
    firstFrameAt: null,
    sortMs: null,
    userMoved: false,
  };

  // Focal lengths in canvas pixels: the camera's (times the device pixel ratio) or, fitting, the
  // camera's scaled by min(W / width, H / height) of the canvas and the camera, as render --fit --size WxH.
  function focal() {
    if (state.fit && state.cameraWidth > 0 && state.cameraHeight > 0) {
      const s = Math.min(canvas.width / state.cameraWidth, canvas.height / state.cameraHeight);
      return [state.fx * s, state.fy * s];
    }
    const ratio = window.devicePixelRatio || 1;
    return [state.fx * ratio, state.fy * ratio];
  }

  function setFit(fit) {
    state.fit = fit;
    document.body.classList.toggle("fit", fit);
    $("fit").setAttribute("aria-pressed", String(fit));
  }

  // The poster stands in for the first frame until WebGL draws one (or shows another view).
  function dropPoster() {
    const poster = $("poster");
    if (poster) poster.remove();
  }

  function showMessage(text) {
    state.error = text;
    const box = $("message");
    box.textContent = text;
    box.hidden = false;
  }

  // ---------------------------------------------------------------- WebGL

  const gl = canvas.getContext("webgl2", {
    antialias: false, alpha: true, premultipliedAlpha: true, depth: false, stencil: false,
    preserveDrawingBuffer: false,
  });
  let program = null, quadBuffer = null, uniforms = {};

  function setUpGL() {
    const vertexSource = ["splat_head.glsl", "splat_instanced.glsl", "fetch_splatv.glsl", "splat_main.glsl"].map(embedded).join("\n");
    const compile = (type, source) => {
      const shader = gl.createShader(type);
      gl.shaderSource(shader, source);
      gl.compileShader(shader);
      if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
      return shader;
    };
    program = gl.createProgram();
    gl.attachShader(program, compile(gl.VERTEX_SHADER, vertexSource));
    gl.attachShader(program, compile(gl.FRAGMENT_SHADER, embedded("splat.frag")));
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
    gl.useProgram(program);
    for (const name of ["projection", "view", "focal", "viewport", "time", "u_texture"]) {
      uniforms[name] = gl.getUniformLocation(program, name);
    }
    quadBuffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, quadBuffer);
    gl.bufferData(gl.ARRAY_BUFFER, QUAD, gl.STATIC_DRAW);
    gl.uniform1i(uniforms.u_texture, 0);
  }

  // ---------------------------------------------------------------- the sort worker

  const worker = new Worker(URL.createObjectURL(new Blob([embedded("sort_worker.js")], {type: "text/javascript"})));
  let sortPending = null; // the request in flight: at most one, the newest view wins next
  let sortId = 0;

  worker.onmessage = (event) => {
    const msg = event.data;
    sortPending = null;
    const seg = state.segments[msg.segment];
    if (!seg || seg.generation !== msg.key.generation) return;
    gl.bindBuffer(gl.ARRAY_BUFFER, seg.indexBuffer);
    gl.bufferData(gl.ARRAY_BUFFER, msg.index, gl.DYNAMIC_DRAW);
    seg.sorted = {count: msg.count, vp: msg.key.vp};
    state.sortMs = msg.ms;
    state.version++;
  };

  function requestSort(seg, vp) {
    if (sortPending) return;
    sortPending = seg.index;
    worker.postMessage({type: "sort", segment: seg.index, id: ++sortId, count: seg.sortable, viewProj: vp,
                        key: {vp: vp.join(","), generation: seg.generation}});
  }

  // ---------------------------------------------------------------- loading

  function segmentBounds() {
    const durations = state.segments.map((s) => (s.duration > 0 ? s.duration : 1));
    const total = durations.reduce((a, b) => a + b, 0);
    const bounds = [0];
    let sum = 0;
    for (const d of durations) { sum += d; bounds.push(sum / total); }
    bounds[bounds.length - 1] = 1;
    return bounds;
  }

  function clipSeconds() {
    return SECONDS_PER_SEGMENT * Math.max(1, state.segments.length);
  }

  // Which segment plays at clip time t, and the time inside it.
  function locate(t) {
    const bounds = segmentBounds();
    const k = state.segments.length;
    let i = 0;
    while (i < k - 1 && t >= bounds[i + 1]) i++;
    const span = bounds[i + 1] - bounds[i];
    return {index: i, time: k === 1 ? t : (t - bounds[i]) / span};
  }

  function newSegment(source, index, duration) {
    return {
      source, index, duration, generation: Math.random(), name: source.name,
      header: null, texheight: 0, total: 0, data: null, words: null,
      // A .splatvq's records lie in the texture as its blocks store them; order[k] is the texture
      // record of the k-th in importance order (decode_block's order, a .splatv's of the decoded
      // scene), which the sort draws depth ties in. null: the texture's own order (.splatv).
      order: null,
      // A .splatvq's inflate and decode time (summed over blocks), when its first and last bytes arrived.
      format: "splatv", decodeMs: null, firstByteAt: null, lastByteAt: null, loadedAt: null,
      received: 0,   // texture bytes arrived
      uploaded: 0,   // records uploaded to the texture
      sortable: 0,   // records whose positions the worker holds
      done: false, failed: false,
      texture: null, indexBuffer: gl.createBuffer(), vao: null, sorted: null,
    };
  }

  function describeFailure(seg, text) {
    seg.failed = true;
    showMessage(`Cannot show ${seg.name}: ${text}`);
  }

  // Parse the preamble and JSON header; returns the byte offset of the texture
  // data, 0 when more bytes are needed, or throws an Error with a plain message.
  function parseHeader(bytes) {
    if (bytes.length < 8) return 0;
    const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    if (dv.getUint32(0, true) !== MAGIC) {
      const start = new TextDecoder().decode(bytes.subarray(0, 4));
      if (start.startsWith("ply")) {
        throw new Error("this is a PLY file; the player reads .splatv (convert it with " +
                        "`splatconv convert scene.ply scene.splatv`, or open it with `splatconv view`).");
      }
      throw new Error("this is not a .splatv or .splatvq file (it starts with neither's signature).");
    }
    const jsonLength = dv.getUint32(4, true);
    if (jsonLength > 64 * 1024 * 1024) throw new Error("its header is damaged (it claims a header of " +
                                                       `${jsonLength} bytes).`);
    if (bytes.length < 8 + jsonLength) return 0;
    let chunks;
    try {
      chunks = JSON.parse(new TextDecoder("utf-8", {fatal: true}).decode(bytes.subarray(8, 8 + jsonLength)));
    } catch (e) {
      throw new Error("its header is damaged (not valid JSON).");
    }
    if (!Array.isArray(chunks)) throw new Error("its header is damaged (not a list of chunks).");
    let offset = 8 + jsonLength;
    for (const chunk of chunks) {
      if (!chunk || typeof chunk !== "object" || !Number.isInteger(chunk.size) || chunk.size < 0) {
        throw new Error("its header is damaged (a chunk without a valid size).");
      }
      if (chunk.type === "splat") {
        const h = chunk.texheight, maxRows = gl.getParameter(gl.MAX_TEXTURE_SIZE);
        if (chunk.texwidth !== TEXWIDTH || !Number.isInteger(h) || h < 1) {
          throw new Error("its splat texture is not the 4096-wide texture the viewer draws.");
        }
        if (chunk.size !== TEXWIDTH * h * 16) throw new Error("its splat chunk size does not match its texture.");
        if (h > maxRows) {
          throw new Error(`it holds ${h * SPLATS_PER_ROW} splat slots, more than this browser's GPU ` +
                          `can hold in one texture (${maxRows * SPLATS_PER_ROW}).`);
        }
        return {offset, chunk};
      }
      offset += chunk.size;
    }
    throw new Error("it holds no splats (its header has no 'splat' chunk).");
  }

  function startTexture(seg, chunk) {
    seg.header = chunk;
    seg.texheight = chunk.texheight;
    seg.total = chunk.texheight * SPLATS_PER_ROW;
    seg.data = new Uint8Array(seg.total * RECORD_BYTES);
    seg.words = new Uint32Array(seg.data.buffer);
    seg.floats = new Float32Array(seg.data.buffer);
    seg.texture = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, seg.texture);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32UI, TEXWIDTH, seg.texheight);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    seg.vao = gl.createVertexArray();
    gl.bindVertexArray(seg.vao);
    gl.bindBuffer(gl.ARRAY_BUFFER, quadBuffer);
    const position = gl.getAttribLocation(program, "position");
    gl.enableVertexAttribArray(position);
    gl.vertexAttribPointer(position, 2, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, seg.indexBuffer);
    const index = gl.getAttribLocation(program, "index");
    gl.enableVertexAttribArray(index);
    gl.vertexAttribIPointer(index, 1, gl.INT, 0, 0);
    gl.vertexAttribDivisor(index, 1);
    gl.bindVertexArray(null);
    if (seg.index === 0 && Array.isArray(chunk.cameras) && chunk.cameras.length) setCameras(chunk.cameras);
  }

  async function load(seg) {
    let reader;
    try {
      if (seg.source.file) {
        reader = seg.source.file.stream().getReader();
      } else {
        const response = await fetch(seg.source.url);
        if (!response.ok) throw new Error(`the server answered ${response.status} ${response.statusText}.`);
        seg.expected = Number(response.headers.get("Content-Length")) || 0;
        reader = response.body.getReader();
      }
    } catch (e) {
      const offline = location.protocol === "file:" && !seg.source.url.startsWith("data:");
      describeFailure(seg, offline ? "a page opened from disk cannot fetch a separate scene file; serve the " +
                      "folder with a web server (or use `splatconv view`), or drop the .splatv file here."
                      : e.message || String(e));
      return;
    }
    let head = new Uint8Array(0), offset = null, got = 0;
    try {
      for (;;) {
        const {done, value} = await reader.read();
        if (done) break;
        got += value.length;
        if (state.firstMegabyteAt === null && got >= 1 << 20) state.firstMegabyteAt = performance.now();
        let bytes = value;
        if (offset === null) {
          const joined = new Uint8Array(head.length + value.length);
          joined.set(head);
          joined.set(value, head.length);
          head = joined;
          if (isSplatvq(head)) {
            await loadSplatvq(seg, reader, head);
            return;
          }
          const parsed = parseHeader(head);
          if (!parsed) continue;
          offset = parsed.offset;
          startTexture(seg, parsed.chunk);
          bytes = head.subarray(Math.min(offset, head.length));
          offset = Math.max(0, offset - head.length); // bytes still to skip (other chunks)
          head = null;
        }
        if (offset > 0) {
          const skip = Math.min(offset, bytes.length);
          offset -= skip;
          bytes = bytes.subarray(skip);
        }
        const room = seg.data.length - seg.received;
        if (room > 0 && bytes.length) {
          seg.data.set(bytes.subarray(0, room), seg.received);
          seg.received += Math.min(room, bytes.length);
        }
      }
      if (offset === null) {
        parseHeader(head); // throws for a file that is not .splatv at all
        throw new Error("the file ends inside its header (too short to be a .splatv scene).");
      }
    } catch (e) {
      describeFailure(seg, e.message || String(e));
      return;
    }
    // A file that stops after its last record, as splaTV's converter writes them, is whole: the rest of the
    // texture is zeros, as `splatconv render` reads it. Only a file that ends inside a record, or before the
    // splats its header counts, was cut short (formats/splatv.py notes the same).
    const present = Math.ceil(seg.received / RECORD_BYTES), cut = seg.received % RECORD_BYTES;
    const counted = seg.header.count;
    if (cut) {
      seg.note = `the file ends inside splat ${present - 1} (after ${cut} of its ${RECORD_BYTES} bytes): ` +
        "truncated? its missing bytes read as zeros";
    } else if (Number.isInteger(counted) && counted > present && counted <= seg.total) {
      seg.note = `the file holds ${present.toLocaleString()} of the ${counted.toLocaleString()} splats its ` +
        "header counts: truncated?";
    }
    seg.received = seg.data.length;
    seg.count = splatCount(seg, present);
    seg.done = true;
    // A frame reports completeness with "done": redraw, in case the last records were already drawn
    // sorted before this line ran (a paused page otherwise never draws again: seen under load).
    state.version++;
    seg.loadedAt = performance.now();
  }

  // Splats in a loaded segment of ``present`` records, as formats/splatv.py counts them: the header's count
  // (splatconv's writer stores it) where every record after it is zero, else the records up to the last one
  // that is not all zero (other writers store no count; the rest of their texture is padding).
  function splatCount(seg, present) {
    const count = seg.header.count;
    let last = seg.words.length;
    while (last > 0 && seg.words[last - 1] === 0) last--;
    const used = Math.ceil(last / 16);
    if (Number.isInteger(count) && count >= 0 && count <= seg.total && used <= count) return Math.min(count, present);
    return used;
  }

  // A .splatvq file (specs/splatvq.md) starts with "SPVQ"; anything else is read as .splatv.
  function isSplatvq(bytes) {
    return bytes.length >= 4 && bytes[0] === 0x53 && bytes[1] === 0x50 && bytes[2] === 0x56 && bytes[3] === 0x51;
  }

  function startDecoder(given) {
    const source = given || embedded("splatvq_decode.js");
    const decoder = new Worker(URL.createObjectURL(new Blob([source], {type: "text/javascript"})));
    decoder.postMessage({type: "init", source}); // it starts helpers from it, to decode blocks in parallel
    return decoder;
  }

  // Stream a .splatvq into the decode worker (splatvq_decode.js): its blocks come back
  // as .splatv texture records, each block's in the order it stores them, with their
  // importance order beside them (seg.order), and land where a .splatv's bytes would;
  // uploading and drawing are the same from here on, and the sort draws depth ties in
  // importance order, as it draws a .splatv of the decoded scene.
  async function loadSplatvq(seg, reader, first) {
    const decoder = startDecoder();
    let failure = null;
    const finished = new Promise((resolve) => {
      const stop = (message) => { failure = failure || message; resolve(); };
      decoder.onerror = (event) => { event.preventDefault(); stop(`the decoder failed (${event.message}).`); };
      decoder.onmessage = (event) => {
        const msg = event.data;
        if (msg.type === "header") {
          const texheight = Math.ceil(msg.count / SPLATS_PER_ROW), maxRows = gl.getParameter(gl.MAX_TEXTURE_SIZE);
          if (texheight > maxRows) {
            stop(`it holds ${msg.count} splats, more than this browser's GPU can hold in one texture ` +
                 `(${maxRows * SPLATS_PER_ROW}).`);
            return;
          }
          seg.format = "splatvq";
          seg.decodeMs = 0;
          startTexture(seg, {texheight, count: msg.count, cameras: msg.cameras});
          seg.order = new Uint32Array(seg.total);
          for (let k = 0; k < seg.total; k++) seg.order[k] = k; // a block's own order, the padding's
        } else if (msg.type === "block") {
          // Blocks arrive in file order: every record before this block's end is in. The file is in
          // importance order block after block, so a record's rank is its block's start plus its rank
          // in the block.
          seg.data.set(new Uint8Array(msg.words.buffer), msg.start * RECORD_BYTES);
          if (msg.order) for (let k = 0; k < msg.count; k++) seg.order[msg.start + k] = msg.start + msg.order[k];
          seg.received = (msg.start + msg.count) * RECORD_BYTES;
          seg.decodeMs += msg.ms;
        } else if (msg.type === "done") {
          resolve();
        } else if (msg.type === "error") {
          stop(msg.message);
        }
      };
    });
    const send = (bytes) => {
      // Hand the bytes over without a copy where they fill their buffer.
      const whole = bytes.byteOffset === 0 && bytes.byteLength === bytes.buffer.byteLength;
      const data = whole ? bytes.buffer : bytes.slice().buffer;
      decoder.postMessage({type: "bytes", data}, [data]);
    };
    let got = first.length;
    seg.firstByteAt = performance.now();
    try {
      send(first);
      while (failure === null) {
        const {done, value} = await reader.read();
        if (done) break;
        got += value.length;
        if (state.firstMegabyteAt === null && got >= 1 << 20) state.firstMegabyteAt = performance.now();
        send(value);
      }
    } catch (e) {
      failure = failure || (e.message || String(e));
    }
    seg.lastByteAt = performance.now();
    if (failure === null) {
      decoder.postMessage({type: "end"});
      await finished; // "done", or an error found in the last blocks
    } else {
      reader.cancel().catch(() => {});
    }
    decoder.terminate();
    if (failure !== null) {
      describeFailure(seg, failure);
      return;
    }
    seg.received = seg.data.length;
    seg.count = seg.header.count; // the block table's count: every splat decoded, none padding
    seg.done = true;
    seg.loadedAt = performance.now();
    state.version++; // redraw once complete, as a .splatv's load does
  }

  // Upload whatever arrived since the last frame and hand the positions to the worker, in
  // importance order with the texture record of each where that is not the texture's order
  // (whole blocks arrive at once: the records of [uploaded, records) are those ranked there).
  function pump(seg) {
    if (!seg.texture) return;
    const records = seg.done ? seg.total : Math.floor(seg.received / RECORD_BYTES);
    if (records <= seg.uploaded) return;
    const firstRow = Math.floor(seg.uploaded / SPLATS_PER_ROW);
    const lastRow = Math.ceil(records / SPLATS_PER_ROW);
    gl.bindTexture(gl.TEXTURE_2D, seg.texture);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, firstRow, TEXWIDTH, lastRow - firstRow, gl.RGBA_INTEGER,
                     gl.UNSIGNED_INT, seg.words, firstRow * TEXWIDTH * 4);
    const n = records - seg.uploaded;
    const positions = new Float32Array(n * 3), order = seg.order ? seg.order.slice(seg.uploaded, records) : null;
    for (let i = 0, k = seg.uploaded; i < n; i++, k++) {
      const r = 16 * (order ? order[i] : k);
      positions[3 * i] = seg.floats[r];
      positions[3 * i + 1] = seg.floats[r + 1];
      positions[3 * i + 2] = seg.floats[r + 2];
    }
    worker.postMessage({type: "append", segment: seg.index, start: seg.uploaded, total: seg.total, positions, order},
                       order ? [positions.buffer, order.buffer] : [positions.buffer]);
    if (seg.index === 0 && seg.uploaded === 0 && !state.userMoved) framePivot(seg, records);
    seg.uploaded = records;
    seg.sortable = records;
    // The texture and the worker hold it all now: free the page's copy.
    if (seg.done && records === seg.total) seg.data = seg.words = seg.floats = null;
  }

  // Orbit about the scene's middle depth, from the first records (the most important).
  function framePivot(seg, records) {
    const v = state.view;
    const depths = [];
    for (let i = 0; i < Math.min(records, 4096); i++) {
      const r = 16 * (seg.order ? seg.order[i] : i), x = seg.floats[r], y = seg.floats[r + 1], z = seg.floats[r + 2];
      const d = v[2] * x + v[6] * y + v[10] * z + v[14];
      if (Number.isFinite(d) && d > 0) depths.push(d);
    }
    if (depths.length) {
      depths.sort((a, b) => a - b);
      state.pivot = Math.max(0.2, depths[depths.length >> 1]);
    }
  }

  async function loadAll(sources) {
    for (const seg of state.segments) {
      worker.postMessage({type: "forget", segment: seg.index});
      if (seg.texture) gl.deleteTexture(seg.texture);
      gl.deleteBuffer(seg.indexBuffer);
    }
    state.segments = sources.map((s, i) => newSegment(s, i, s.duration));
    state.version++;
    state.firstMegabyteAt = state.firstFrameAt = null;
    $("message").hidden = true;
    state.error = null;
    // In order, so the segment that plays first is complete first and the next one
    // is already loaded when the clip reaches it.
    for (const seg of state.segments) {
      await load(seg);
      if (seg.failed) return;
    }
  }

  // ---------------------------------------------------------------- cameras and the URL hash

  function setCameras(cameras) {
    state.cameras = cameras;
    const select = $("camera");
    select.textContent = "";
    cameras.forEach((c, i) => {
      const option = document.createElement("option");
      option.value = String(i);
      option.textContent = `${i}: ${c.img_name || "camera " + i}`;
      select.appendChild(option);
    });
    $("camera-box").hidden = cameras.length === 0;
    if (!state.viewFromHash) useCamera(0, false);
    else setFocal(cameras[0]);
  }

  function setFocal(camera) {
    if (Number(camera.fx) > 0 && Number(camera.fy) > 0) { state.fx = Number(camera.fx); state.fy = Number(camera.fy); }
    const w = Number(camera.width), h = Number(camera.height);
    [state.cameraWidth, state.cameraHeight] = w > 0 && h > 0 ? [w, h] : [0, 0];
  }

  function useCamera(i, fromUser) {
    const camera = state.cameras[i];
    if (!camera) return;
    state.view = cameraView(camera);
    setFocal(camera);
    $("camera").value = String(i);
    if (fromUser) writeHash();
  }

  // A hash pasted by hand may hold a broken %-escape: read such a part as it is.
  function decoded(text) {
    try { return decodeURIComponent(text); } catch (e) { return text; }
  }

  function parseMatrix(text) {
    let values;
    try { values = JSON.parse(decoded(text)); } catch (e) { return null; }
    if (!Array.isArray(values) || values.length !== 16 || !values.every((v) => typeof v === "number" && Number.isFinite(v))) {
      return null;
    }
    return values;
  }

  // `#view=[16 numbers]&t=0.35&ui=0`, or splaTV's bare `#[16 numbers]`.
  function readHash() {
    const hash = location.hash.replace(/^#/, "");
    if (!hash) return;
    const params = {};
    if (decoded(hash).startsWith("[")) {
      params.view = hash;
    } else {
      for (const part of hash.split("&")) {
        const at = part.indexOf("=");
        if (at > 0) params[part.slice(0, at)] = part.slice(at + 1);
      }
    }
    if (params.view !== undefined) {
      const m = parseMatrix(params.view);
      if (m) { state.view = m; state.viewFromHash = true; dropPoster(); }
    }
    if (params.t !== undefined && params.t !== "") {
      const t = Number(decoded(params.t));
      if (Number.isFinite(t)) { state.time = Math.min(1, Math.max(0, t)); setPlaying(false); }
    }
    if (params.ui !== undefined) document.body.classList.toggle("noui", params.ui === "0");
    if (params.fit === "1" || params.fit === "0") setFit(params.fit === "1");
  }

  let hashTimer = null;
  function writeHash() {
    clearTimeout(hashTimer);
    hashTimer = setTimeout(() => {
      let hash = "view=" + JSON.stringify(state.view);
      if (!state.playing) hash += "&t=" + state.time;
      if (document.body.classList.contains("noui")) hash += "&ui=0";
      if (state.fit !== !!config.fit) hash += "&fit=" + (state.fit ? 1 : 0);
      history.replaceState(null, "", "#" + hash);
    }, 150);
  }

  // ---------------------------------------------------------------- time

  function setPlaying(playing) {
    state.playing = playing;
    $("play").textContent = playing ? "❚❚" : "▶";
    $("play").title = playing ? "Pause (space)" : "Play (space)";
  }

  function advance(seconds) {
    if (!state.playing) return;
    let t = state.time + state.direction * state.speed * seconds / clipSeconds();
    if (state.mode === "loop") {
      t -= Math.floor(t);
    } else if (t > 1 || t < 0) {
      t = t > 1 ? 2 - t : -t;
      state.direction = -state.direction;
      t = Math.min(1, Math.max(0, t));
    }
    state.time = t;
  }

  // ---------------------------------------------------------------- controls

  function move(m) {
    state.view = multiply(m, state.view);
    state.userMoved = true;
    writeHash();
  }

  function orbit(dx, dy) {
    const d = state.pivot;
    move(multiply(translation(0, 0, d), multiply(multiply(rotation(dy, "x"), rotation(-dx, "y")), translation(0, 0, -d))));
  }

  function pan(dxPixels, dyPixels) {
    const [fx, fy] = focal(), scale = state.pivot / fx;
    move(translation(dxPixels * scale, dyPixels * (fx / fy) * scale, 0));
  }

  function zoom(factor) {
    const d = state.pivot, next = Math.min(1000, Math.max(0.05, d * factor));
    state.pivot = next;
    move(translation(0, 0, next - d));
  }

  const pointers = new Map();
  let pinch = null;

  function pinchState() {
    const [a, b] = [...pointers.values()];
    return {distance: Math.hypot(a.x - b.x, a.y - b.y), x: (a.x + b.x) / 2, y: (a.y + b.y) / 2};
  }

  canvas.addEventListener("pointerdown", (e) => {
    canvas.setPointerCapture(e.pointerId);
    pointers.set(e.pointerId, {x: e.clientX, y: e.clientY, button: e.button, pan: e.button !== 0 || e.shiftKey || e.ctrlKey});
    if (pointers.size === 2) pinch = pinchState();
  });
  canvas.addEventListener("pointermove", (e) => {
    const p = pointers.get(e.pointerId);
    if (!p) return;
    const dx = e.clientX - p.x, dy = e.clientY - p.y;
    p.x = e.clientX;
    p.y = e.clientY;
    if (pointers.size === 2) {
      const now = pinchState();
      if (pinch && now.distance > 0) {
        zoom(pinch.distance / now.distance);
        pan(now.x - pinch.x, now.y - pinch.y);
      }
      pinch = now;
    } else if (pointers.size === 1) {
      if (p.pan) pan(dx, dy);
      else orbit(dx * 0.005, dy * 0.005);
    }
  });
  const release = (e) => { pointers.delete(e.pointerId); pinch = pointers.size === 2 ? pinchState() : null; };
  canvas.addEventListener("pointerup", release);
  canvas.addEventListener("pointercancel", release);
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    const lines = e.deltaMode === 1 ? 30 : e.deltaMode === 2 ? 300 : 1;
    zoom(Math.exp(e.deltaY * lines * 0.001));
  }, {passive: false});

  window.addEventListener("keydown", (e) => {
    if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement) {
      if (e.key !== " ") return;
    }
    const step = 0.05, px = 20;
    const actions = {
      ArrowLeft: () => (e.shiftKey ? pan(px, 0) : orbit(-step, 0)),
      ArrowRight: () => (e.shiftKey ? pan(-px, 0) : orbit(step, 0)),
      ArrowUp: () => (e.shiftKey ? pan(0, px) : orbit(0, -step)),
      ArrowDown: () => (e.shiftKey ? pan(0, -px) : orbit(0, step)),
      w: () => zoom(0.9), s: () => zoom(1 / 0.9), "+": () => zoom(0.9), "=": () => zoom(0.9), "-": () => zoom(1 / 0.9),
      a: () => pan(px, 0), d: () => pan(-px, 0),
      " ": () => { setPlaying(!state.playing); writeHash(); },
      "[": () => useCamera((Number($("camera").value) + state.cameras.length - 1) % state.cameras.length, true),
      "]": () => useCamera((Number($("camera").value) + 1) % state.cameras.length, true),
      h: () => { document.body.classList.toggle("noui"); },
      f: () => { setFit(!state.fit); writeHash(); },
    };
    const action = actions[e.key.length === 1 ? e.key.toLowerCase() : e.key] || actions[e.key];
    if (action) { e.preventDefault(); action(); }
  });

  $("play").addEventListener("click", () => { setPlaying(!state.playing); writeHash(); });
  $("fit").addEventListener("click", () => { setFit(!state.fit); writeHash(); });
  $("time").addEventListener("input", () => {
    state.time = Number($("time").value);
    setPlaying(false);
    writeHash();
  });
  $("speed").addEventListener("change", () => { state.speed = Number($("speed").value); });
  $("mode").addEventListener("change", () => { state.mode = $("mode").value; state.direction = 1; });
  $("camera").addEventListener("change", () => { useCamera(Number($("camera").value), true); state.userMoved = true; });
  window.addEventListener("hashchange", () => { readHash(); });

  // Drag and drop a .splatv or .splatvq file onto the page.
  window.addEventListener("dragover", (e) => { e.preventDefault(); document.body.classList.add("dropping"); });
  window.addEventListener("dragleave", () => document.body.classList.remove("dropping"));
  window.addEventListener("drop", (e) => {
    e.preventDefault();
    document.body.classList.remove("dropping");
    const files = [...(e.dataTransfer ? e.dataTransfer.files : [])];
    if (!files.length) return;
    files.sort((a, b) => a.name.localeCompare(b.name, undefined, {numeric: true}));
    state.viewFromHash = false;
    state.userMoved = false;
    dropPoster();
    loadAll(files.map((file) => ({file, name: file.name})));
  });

  // ---------------------------------------------------------------- drawing

  function resize() {
    const ratio = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * ratio));
    const h = Math.max(1, Math.round(canvas.clientHeight * ratio));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  }

  function draw() {
    resize();
    const w = canvas.width, h = canvas.height, [fx, fy] = focal();
    const projection = projectionMatrix(fx, fy, w, h);
    const vp = multiply(projection, state.view);
    const vpKey = vp.join(",");
    const where = locate(state.time);
    const seg = state.segments[where.index];
    gl.viewport(0, 0, w, h);
    gl.disable(gl.DEPTH_TEST);
    gl.disable(gl.CULL_FACE);
    gl.enable(gl.BLEND);
    gl.blendFuncSeparate(gl.ONE_MINUS_DST_ALPHA, gl.ONE, gl.ONE_MINUS_DST_ALPHA, gl.ONE);
    gl.blendEquation(gl.FUNC_ADD);
    gl.clearColor(0, 0, 0, 0);
    gl.clear(gl.COLOR_BUFFER_BIT);
    let drawn = 0;
    if (seg && seg.vao && seg.sorted && seg.sorted.count > 0) {
      gl.useProgram(program);
      gl.uniformMatrix4fv(uniforms.projection, false, new Float32Array(projection));
      gl.uniformMatrix4fv(uniforms.view, false, new Float32Array(state.view));
      gl.uniform2f(uniforms.focal, fx, fy);
      gl.uniform2f(uniforms.viewport, w, h);
      gl.uniform1f(uniforms.time, where.time);
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, seg.texture);
      gl.bindVertexArray(seg.vao);
      gl.drawArraysInstanced(gl.TRIANGLE_FAN, 0, 4, seg.sorted.count);
      gl.bindVertexArray(null);
      drawn = seg.sorted.count;
    }
    // What this frame showed; a test waits until it is the whole segment, sorted for this view.
    state.drawnKey = {
      segment: where.index, time: where.time, clipTime: state.time, count: drawn, vp: vpKey,
      complete: !!(seg && seg.done && drawn === seg.total && seg.sorted.vp === vpKey),
    };
    if (drawn && state.firstFrameAt === null) state.firstFrameAt = performance.now();
    if (drawn) dropPoster();
    return {seg, vp, vpKey, where};
  }

  function geometry() {
    const [fx, fy] = focal();
    const vp = multiply(projectionMatrix(fx, fy, canvas.width, canvas.height), state.view);
    const where = locate(state.time);
    return {seg: state.segments[where.index], vp, vpKey: vp.join(","), where};
  }

  function frame(now) {
    const seconds = state.lastFrame ? Math.min(0.25, (now - state.lastFrame) / 1000) : 0;
    advance(seconds);
    for (const seg of state.segments) pump(seg);
    if (state.view) {
      // Redraw only when something visible changed: a paused, settled page costs nothing.
      const key = JSON.stringify([state.view, state.fx, state.fy, state.fit, canvas.clientWidth, canvas.clientHeight,
                                  window.devicePixelRatio, state.time, state.version]);
      if (key !== state.lastDrawKey) {
        draw();
        state.lastDrawKey = key;
        // Frame time: the interval between consecutive drawn frames.
        if (state.drewLast) {
          const ms = now - state.lastFrame;
          state.frameMs = state.frameMs ? state.frameMs * 0.8 + ms * 0.2 : ms;
        }
        state.drewLast = true;
      } else {
        state.drewLast = false;
      }
      const {seg, vp, vpKey, where} = geometry();
      // Sort what plays now; when it is current, the segment that plays next.
      if (seg && seg.sortable && (!seg.sorted || seg.sorted.vp !== vpKey || seg.sorted.count !== seg.sortable)) {
        requestSort(seg, vp);
      } else {
        const next = state.segments[where.index + (state.direction > 0 ? 1 : -1)];
        if (next && next.sortable && (!next.sorted || next.sorted.vp !== vpKey || next.sorted.count !== next.sortable)) {
          requestSort(next, vp);
        }
      }
    }
    state.frames++;
    state.lastFrame = now;
    updatePanel();
    requestAnimationFrame(frame);
  }

  function updatePanel() {
    if (!$("time").matches(":active")) $("time").value = String(state.time);
    $("time-label").textContent = state.time.toFixed(3);
    const total = state.segments.reduce((a, s) => a + s.total * RECORD_BYTES, 0);
    const got = state.segments.reduce((a, s) => a + s.received, 0);
    const done = state.segments.length && state.segments.every((s) => s.done);
    const where = locate(state.time);
    const seg = state.segments[where.index];
    const parts = [];
    if (seg && seg.header) {
      // Once loaded, the splats counted as formats/splatv.py counts them; while loading, splatconv's writer's
      // count (COUNT_KEY in formats/splatv_layout.py) where there is one, else the records so far.
      const count = seg.done ? seg.count : seg.header.count;
      parts.push(Number.isInteger(count) && count >= 0 && count <= seg.total
        ? `${count.toLocaleString()} splats`
        : `${Math.floor(seg.received / RECORD_BYTES).toLocaleString()} splats so far`);
    }
    if (state.segments.length > 1) parts.push(`segment ${where.index + 1} of ${state.segments.length}`);
    // No frame drawn twice in a row yet (paused from the start): nothing measured, so no number.
    parts.push(state.frameMs ? `${state.frameMs.toFixed(1)} ms/frame` : "– ms/frame");
    if (state.sortMs !== null) parts.push(`sort ${state.sortMs.toFixed(1)} ms`);
    $("stats").textContent = parts.join(" · ");
    const progress = $("progress");
    progress.hidden = !!done || !total;
    progress.value = total ? got / total : 0;
    const notes = state.segments.filter((s) => s.note).map((s) => `${s.name}: ${s.note}`);
    $("note").textContent = notes.join("; ");
  }

  // ---------------------------------------------------------------- test and scripting hooks

  function status() {
    const d = state.drawnKey;
    const [fx, fy] = focal();
    const vpNow = state.view ? multiply(projectionMatrix(fx, fy, canvas.width, canvas.height), state.view).join(",") : null;
    return {
      // The last frame showed the whole scene sorted for the current view, at the current time.
      settled: !!(d && d.complete && d.vp === vpNow && (state.playing || d.clipTime === state.time)),
      error: state.error,
      loaded: state.segments.length > 0 && state.segments.every((s) => s.done),
      drawn: state.drawnKey,
      time: state.time, playing: state.playing, view: state.view, fx: state.fx, fy: state.fy,
      fit: state.fit, focal: [fx, fy], poster: !!$("poster"),
      width: canvas.width, height: canvas.height, hash: location.hash,
      segments: state.segments.map((s) => ({name: s.name, total: s.total, received: s.received, done: s.done,
                                            count: s.done ? s.count : null, note: s.note || null,
                                            format: s.format, decodeMs: s.decodeMs, firstByteAt: s.firstByteAt,
                                            lastByteAt: s.lastByteAt, loadedAt: s.loadedAt})),
      firstMegabyteAt: state.firstMegabyteAt, firstFrameAt: state.firstFrameAt, sortMs: state.sortMs,
    };
  }

  // Draw now and read the framebuffer back: base64 of top-row-first RGBA bytes.
  function capture() {
    draw();
    const w = canvas.width, h = canvas.height;
    const pixels = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
    const flipped = new Uint8Array(pixels.length), row = w * 4;
    for (let y = 0; y < h; y++) flipped.set(pixels.subarray((h - 1 - y) * row, (h - y) * row), y * row);
    let text = "";
    for (let i = 0; i < flipped.length; i += 0x8000) text += String.fromCharCode.apply(null, flipped.subarray(i, i + 0x8000));
    return {width: w, height: h, rgba: btoa(text), drawn: state.drawnKey};
  }

  // Sort the scene for a given view in the worker and report the milliseconds (bench).
  function benchSort(segment, viewProj) {
    return new Promise((resolve) => {
      const listener = (event) => {
        if (event.data.id !== -1) return;
        worker.removeEventListener("message", listener);
        resolve({ms: event.data.ms, count: event.data.count});
      };
      worker.addEventListener("message", listener);
      const seg = state.segments[segment];
      worker.postMessage({type: "sort", segment, id: -1, count: seg.sortable, viewProj, key: {vp: "", generation: -1}});
    });
  }

  // The texture's words as the GPU holds them (tests compare them with splatconv's decoder):
  // base64 of texheight rows of 4096 RGBA32UI texels, little endian.
  function textureWords(segment) {
    const seg = state.segments[segment];
    if (!seg || !seg.texture) return null;
    const fb = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, seg.texture, 0);
    const words = new Uint32Array(TEXWIDTH * seg.texheight * 4);
    gl.readPixels(0, 0, TEXWIDTH, seg.texheight, gl.RGBA_INTEGER, gl.UNSIGNED_INT, words);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.deleteFramebuffer(fb);
    const bytes = new Uint8Array(words.buffer);
    let text = "";
    for (let i = 0; i < bytes.length; i += 0x8000) text += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
    return btoa(text);
  }

  // Which texture record is k-th in importance order, the order the sort draws depth ties in
  // (tests put the texture's words in it to compare them with splatconv's decoder): base64 of
  // uint32 little endian, or null where it is the texture's own order (.splatv).
  function recordOrder(segment) {
    const seg = state.segments[segment];
    if (!seg || !seg.order) return null;
    const bytes = new Uint8Array(seg.order.buffer, seg.order.byteOffset, seg.order.byteLength);
    let text = "";
    for (let i = 0; i < bytes.length; i += 0x8000) text += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
    return btoa(text);
  }

  // Decode the .splatvq at `url` in the decode workers, all its bytes in memory first and
  // nothing drawn (bench): the wall milliseconds, the splats, the blocks' summed work.
  // `source`: another decoder's source to time instead of the page's (bench_web.py --baseline).
  async function benchDecode(url, source) {
    const bytes = new Uint8Array(await (await fetch(url)).arrayBuffer());
    const decoder = startDecoder(source);
    return new Promise((resolve) => {
      let splats = 0, blockMs = 0, inflateMs = 0;
      const t0 = performance.now();
      decoder.onmessage = (event) => {
        const msg = event.data;
        if (msg.type === "block") {
          splats += msg.count;
          blockMs += msg.ms;
          inflateMs += msg.inflateMs;
        } else if (msg.type === "done" || msg.type === "error") {
          decoder.terminate();
          resolve({ms: performance.now() - t0, splats, blockMs, inflateMs, error: msg.message || null});
        }
      };
      decoder.postMessage({type: "bytes", data: bytes.buffer}, [bytes.buffer]);
      decoder.postMessage({type: "end"});
    });
  }

  window.splatconvPlayer = {status, capture, benchSort, benchDecode, textureWords, recordOrder,
                            useCamera: (i) => useCamera(i, true)};

  // ---------------------------------------------------------------- start

  // The hash first, so that without WebGL too the poster is laid out (or dropped) as it asks.
  state.view = cameraView({rotation: [[1, 0, 0], [0, 1, 0], [0, 0, 1]], position: [0, 0, -4]});
  setPlaying(true);
  setFit(state.fit);
  readHash();
  if (!gl) {
    showMessage("This browser cannot show the scene: WebGL 2 is not available (it may be turned off in " +
                "the browser's settings, or the graphics driver is not supported).");
    return;
  }
  try {
    setUpGL();
  } catch (e) {
    showMessage(`This browser's WebGL could not compile the splat shader: ${e.message}`);
    return;
  }
  canvas.addEventListener("webglcontextlost", () => showMessage("The graphics context was lost; reload the page."));
  requestAnimationFrame(frame);
  const sources = config.scenes.map((s, i) => {
    if (s.embedded !== undefined) {
      return {url: "data:application/octet-stream;base64," + embedded(s.embedded).replace(/\s+/g, ""),
              name: s.name, duration: s.duration};
    }
    return {url: s.url, name: s.name, duration: s.duration};
  });
  if (sources.length) loadAll(sources);
  else showMessage("Drop a .splatv or .splatvq file here to view it.");
})();
