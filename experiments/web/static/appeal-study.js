/* Appeal Lab: a rating protocol in the browser (written by `appeal export web`).
 *
 * jsPsych runs the timeline (preload, full screen, instruction pages); the plugin below runs one
 * trial of the protocol's list exactly as the lab runner does: fixation (before or after), the face
 * for a counted number of display frames (requestAnimationFrame) - or a clip, its frames decoded
 * into bitmaps before the trial and drawn on a canvas one per refresh/fps animation frames - the
 * Likert / classification screens, the inter-trial interval. Every finished trial's row is kept in localStorage at once, so
 * a reload continues at the next trial; at the end the `_beh.tsv` is offered for download and,
 * when the export named a data URL, POSTed there.
 */
(function () {
  "use strict";
  const C = window.APPEAL_CONFIG;
  const LISTS = window.APPEAL_TRIALS;
  const P = jsPsychModule.ParameterType;
  const query = new URLSearchParams(window.location.search);

  // ------------------------------------------------------------------ participant and list
  function fnv1a(text) {
    let h = 0x811c9dc5;
    for (let i = 0; i < text.length; i++) {
      h ^= text.charCodeAt(i);
      h = Math.imul(h, 0x01000193) >>> 0;
    }
    return h >>> 0;
  }

  // The importer's limits (experiments/web/session_file.py): a BIDS label of at most 64 characters,
  // URL parameters of at most 256 and a user agent of at most 1024, no control characters.
  const MAX_LABEL = 64;
  const MAX_PARAMETER = 256;
  const MAX_TEXT = 1024;
  function param(name) {
    const v = query.get(name);
    return v ? clean(v, MAX_PARAMETER) : null;
  }
  function clean(text, width) {
    return String(text).replace(/[\u0000-\u001f\u007f-\u009f\u200e\u200f\u202a-\u202e\u2066-\u2069\ufeff]/g, " ").slice(0, width);
  }

  function assign() {
    const given = query.get("participant") || query.get("PROLIFIC_PID") || query.get("workerId") || "";
    const label = given.replace(/[^A-Za-z0-9]/g, "");
    if (!label || label.length > MAX_LABEL) return null;
    const slot = C.participants.includes(label) ? label : C.participants[fnv1a(given) % C.participants.length];
    return {
      participant: label, slot: slot, seed: C.seeds[slot],
      recruitment_pid: param("PROLIFIC_PID") || param("workerId"),
      study_id: param("STUDY_ID"), session_id: param("SESSION_ID"),
    };
  }

  // ------------------------------------------------------------------ storage
  function storageKey(who) {
    return ["appeal", C.name, C.protocol_sha256.slice(0, 12), who.participant, C.session].join(":");
  }
  function load(who) {
    try {
      const s = JSON.parse(window.localStorage.getItem(storageKey(who)) || "null");
      return s && Array.isArray(s.rows) ? s : null;
    } catch (e) {
      return null;
    }
  }
  function save(who, state) {
    window.localStorage.setItem(storageKey(who), JSON.stringify(state));
  }

  // ------------------------------------------------------------------ TSV (the lab runner's format)
  function fmt(v) {
    if (v === null || v === undefined || (typeof v === "number" && isNaN(v))) return "n/a";
    if (typeof v === "boolean") return v ? "1" : "0";
    if (typeof v === "number" && !Number.isInteger(v)) return String(Number(v.toFixed(6)));
    return String(v).replace(/[\t\n]/g, " ");
  }
  function tsv(rows) {
    const lines = [C.columns.join("\t")];
    rows.forEach(function (r) { lines.push(C.columns.map(function (c) { return fmt(r[c]); }).join("\t")); });
    return lines.join("\n") + "\n";
  }
  function fileName(who) {
    return "sub-" + who.participant + "_ses-" + C.session + "_task-" + C.task + "_beh.tsv";
  }

  // ------------------------------------------------------------------ frames
  const clock = { frame: 0, t0: null, hz: C.nominal_hz };
  function countFrames() {
    clock.frame += 1;
    window.requestAnimationFrame(countFrames);
  }
  function seconds(t) { return (t - clock.t0) / 1000; }

  /** Measure the refresh rate: the median interval of 60 animation frames. */
  function measureRefresh() {
    return new Promise(function (resolve) {
      const ts = [];
      function step(t) {
        ts.push(t);
        if (ts.length < 61) { window.requestAnimationFrame(step); return; }
        const d = ts.slice(1).map(function (x, i) { return x - ts[i]; }).sort(function (a, b) { return a - b; });
        const median = d[Math.floor(d.length / 2)];
        resolve(median > 0 ? 1000 / median : C.nominal_hz);
      }
      window.requestAnimationFrame(step);
    });
  }

  /** Draw in the next animation frame and keep it for ``n`` frames; resolves with the flip times. */
  function show(draw, n) {
    return new Promise(function (resolve) {
      const flips = [];
      let onsetFrame = null;
      function step(t) {
        if (!flips.length) { draw(); onsetFrame = clock.frame; }
        flips.push(t);
        if (flips.length >= n) resolve({ onset: flips[0], onsetFrame: onsetFrame, flips: flips });
        else window.requestAnimationFrame(step);
      }
      window.requestAnimationFrame(step);
    });
  }
  // ------------------------------------------------------------------ clips
  /** Flips (animation frames) per clip frame at the measured refresh rate: refresh / fps when it is
   *  whole (as in the lab), else spread evenly (4 and 5 at 144 Hz for 30 fps); ``nominal`` for the data. */
  function clipSchedule(clip) {
    const ratio = clock.hz / clip.fps;
    const whole = Math.round(ratio);
    if (whole >= 1 && Math.abs(ratio - whole) <= C.timing.rate_tolerance * whole) {
      return { perFrame: new Array(clip.n_frames).fill(whole), nominal: whole };
    }
    const perFrame = [];
    for (let k = 0; k < clip.n_frames; k++) perFrame.push(Math.max(1, Math.round((k + 1) * ratio) - Math.round(k * ratio)));
    return { perFrame: perFrame, nominal: Math.round(ratio * 1000) / 1000 };
  }

  /** Every frame of a clip fetched (preloaded by jsPsych), decoded and made a bitmap before its trial. */
  function decodeClip(clip) {
    return Promise.all(clip.frames.map(function (src) {
      const img = new Image();
      img.src = src;
      return img.decode().then(function () { return window.createImageBitmap(img); });
    }));
  }

  /** Play a clip on a canvas: frame k drawn in the first of its perFrame[k] animation frames (counted,
   *  never timed), then the last frame held for ``hold`` more; resolves with what every frame showed. */
  function showClip(display, bitmaps, schedule, hold, title) {
    return new Promise(function (resolve) {
      const n = bitmaps.length;
      const out = { flips: [], frameFlips: new Array(n).fill(0), frameOnsets: [], holdFlips: 0, onsetFrame: null };
      let ctx = null;
      let k = 0;
      let j = 0;
      function step(t) {
        if (ctx === null) { // the first animation frame builds the screen and draws frame 0
          const s = screen(display);
          if (title) at(s, el("div", "appeal-title", title), 0.45);
          const canvas = el("canvas");
          canvas.width = bitmaps[0].width;
          canvas.height = bitmaps[0].height;
          s.appendChild(sized(canvas, C.screen.stimulus_height, 0));
          canvas.className += " appeal-clip";
          ctx = canvas.getContext("2d");
          out.onsetFrame = clock.frame;
        }
        out.flips.push(t);
        if (k < n) {
          if (j === 0) {
            ctx.drawImage(bitmaps[k], 0, 0);
            out.frameOnsets.push(t);
            document.body.dataset.appealClipFrame = String(k);
          }
          out.frameFlips[k] += 1;
          j += 1;
          if (j >= schedule.perFrame[k]) { k += 1; j = 0; }
        } else {
          out.holdFlips += 1;
          document.body.dataset.appealClipHold = String(out.holdFlips);
        }
        if (k >= n && out.holdFlips >= hold) {
          out.onset = out.flips[0];
          resolve(out);
        } else {
          window.requestAnimationFrame(step);
        }
      }
      window.requestAnimationFrame(step);
    });
  }

  /** The lab runner's clip columns of one trial. */
  function clipColumns(clip, schedule, played, preloadMs) {
    let errors = 0;
    played.frameFlips.forEach(function (f, k) { if (f !== schedule.perFrame[k]) errors += 1; });
    return {
      clip_frames: clip.n_frames, clip_fps: clip.fps, clip_flips_per_frame: schedule.nominal,
      clip_frames_shown: played.frameFlips.filter(function (f) { return f > 0; }).length,
      clip_flips: played.frameFlips.reduce(function (a, b) { return a + b; }, 0), clip_hold_flips: played.holdFlips,
      clip_frame_errors: errors, clip_onset_s: seconds(played.frameOnsets[clip.onset_frame]),
      clip_apex_s: seconds(played.frameOnsets[clip.apex_frame]), clip_preload_ms: preloadMs,
    };
  }

  /** The time of the next animation frame: the onset of a screen just built (one that waits for an answer). */
  function nextFrame() {
    return show(function () {}, 1).then(function (r) { return r.onset; });
  }
  function framesAt(nominalFrames) {
    return Math.max(1, Math.round(nominalFrames / C.nominal_hz * clock.hz));
  }

  // ------------------------------------------------------------------ screens
  function el(tag, cls, text) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined && text !== null) e.textContent = text;
    return e;
  }
  /** A full-window screen; ``y`` places a child at a height-unit position (0 centre, +0.5 top). */
  function screen(display) {
    display.innerHTML = "";
    const s = el("div", "appeal-screen");
    display.appendChild(s);
    return s;
  }
  function at(parent, node, y) {
    node.style.top = ((0.5 - y) * 100) + "vh";
    node.classList.add("appeal-at");
    parent.appendChild(node);
    return node;
  }
  function sized(img, height, y) {
    img.className = "appeal-face";
    img.alt = "";
    img.style.height = (height * 100) + "vh";
    img.style.top = ((0.5 - y - height / 2) * 100) + "vh";
    return img;
  }
  function face(parent, src, height, y) {
    const img = new Image();
    img.src = src;
    parent.appendChild(sized(img, height, y));
    return img;
  }

  function waitAnswer(keys, buttons, deadline) {
    return new Promise(function (resolve) {
      let done = false;
      let timer = null;
      function finish(value) {
        if (done) return;
        done = true;
        document.removeEventListener("keydown", onKey);
        if (timer !== null) window.clearTimeout(timer);
        resolve({ value: value, t: performance.now() });
      }
      function onKey(ev) {
        if (Object.prototype.hasOwnProperty.call(keys, ev.key)) { ev.preventDefault(); finish(keys[ev.key]); }
      }
      document.addEventListener("keydown", onKey);
      buttons.forEach(function (b) { b.addEventListener("click", function () { finish(b.dataset.value); }); });
      if (deadline) timer = window.setTimeout(function () { finish(null); }, deadline * 1000);
    });
  }

  function thumb(s, trial) {
    if (C.timing.stimulus_visible_during_response) {
      const h = C.screen.response_stimulus_height;
      face(s, trial.image, h, 0.5 - 0.03 - h / 2);
    }
  }

  async function likert(display, trial, spec) {
    const s = screen(display);
    thumb(s, trial);
    if (spec.description) at(s, el("div", "appeal-description", spec.description), -0.16);
    const row = at(s, el("div", "appeal-likert"), -0.25);
    const buttons = [];
    const keys = {};
    for (let v = 1; v <= spec.points; v++) {
      const b = el("button", "appeal-tick", String(v));
      b.dataset.value = String(v);
      row.appendChild(b);
      buttons.push(b);
      if (spec.keys) keys[String(v)] = String(v);
    }
    const anchors = at(s, el("div", "appeal-anchors"), -0.33);
    anchors.appendChild(el("span", "appeal-low", spec.low));
    anchors.appendChild(el("span", "appeal-high", spec.high));
    if (spec.keys) at(s, el("div", "appeal-hint", "Click on the scale or press 1-" + spec.points), -0.45);
    const onset = await nextFrame();
    const a = await waitAnswer(keys, buttons, C.timing.response_deadline_s);
    return { value: a.value === null ? null : Number(a.value), rt: a.value === null ? null : (a.t - onset) / 1000 };
  }

  async function classify(display, trial, spec) {
    const s = screen(display);
    thumb(s, trial);
    if (spec.prompt) at(s, el("div", "appeal-prompt", spec.prompt), -0.17);
    const row = at(s, el("div", "appeal-choices"), -0.3);
    const width = Math.min(0.24, 1.2 / spec.choices.length - 0.02);
    const buttons = [];
    const keys = {};
    spec.choices.forEach(function (c) {
      const b = el("button", "appeal-choice", c.key ? "[" + c.key + "] " + c.label : c.label);
      b.dataset.value = c.value;
      b.style.width = (width * 100) + "vh";
      row.appendChild(b);
      buttons.push(b);
      if (c.key) keys[c.key] = c.value;
    });
    const onset = await nextFrame();
    const a = await waitAnswer(keys, buttons, C.timing.response_deadline_s);
    return { value: a.value, rt: a.value === null ? null : (a.t - onset) / 1000 };
  }

  async function respond(display, trial, row) {
    for (const spec of C.responses) {
      if (spec.type === "likert") {
        const r = await likert(display, trial, spec);
        row["response_" + spec.name] = r.value;
        row["rt_" + spec.name] = r.rt;
        continue;
      }
      const r = await classify(display, trial, spec);
      row["response_" + spec.name] = r.value;
      row["rt_" + spec.name] = r.rt;
      if (spec.factor) row["correct_" + spec.name] = r.value === null ? null : Number(r.value === trial.factors[spec.factor]);
      if (spec.intensity) {
        const skip = r.value === null || spec.skip_intensity_for.includes(r.value);
        if (skip) {
          row["response_" + spec.intensity.name] = r.value === null ? null : spec.skip_value;
          row["rt_" + spec.intensity.name] = null;
        } else {
          const i = await likert(display, trial, spec.intensity);
          row["response_" + spec.intensity.name] = i.value;
          row["rt_" + spec.intensity.name] = i.rt;
        }
      }
    }
  }

  function waitKey(key, minS) {
    return new Promise(function (resolve) {
      const ready = performance.now() + (minS || 0) * 1000;
      function onKey(ev) {
        if (ev.key === key && performance.now() >= ready) {
          document.removeEventListener("keydown", onKey);
          resolve();
        }
      }
      document.addEventListener("keydown", onKey);
    });
  }

  // ------------------------------------------------------------------ focus and full screen
  const losses = { focus: 0, fullscreen: 0 };
  window.addEventListener("blur", function () { losses.focus += 1; });
  document.addEventListener("fullscreenchange", function () {
    if (!document.fullscreenElement) losses.fullscreen += 1;
  });

  // ------------------------------------------------------------------ the trial plugin
  class AppealTrialPlugin {
    constructor(jsPsych) { this.jsPsych = jsPsych; }

    trial(display, par) {
      const self = this;
      run(display, par.spec).then(function (row) { self.jsPsych.finishTrial(row); });
    }
  }
  AppealTrialPlugin.info = {
    name: "appeal-trial", version: "1.0.0",
    parameters: { spec: { type: P.OBJECT, default: null } },
    data: {},
  };

  let session = null; // {who, state}

  async function run(display, trial) {
    losses.focus = 0;
    losses.fullscreen = 0;
    const who = session.who;
    const row = {
      participant_id: who.participant, session: C.session, part: session.state.part, trial: trial.trial,
      phase: trial.phase, block: trial.block, repetition: trial.repetition, stimulus: trial.stimulus,
      trigger: null, trigger_s: null, trigger_flip_ms: null, list: who.slot, list_trials: LISTS[who.slot].length, seed: who.seed,
      browser: clean(navigator.userAgent, MAX_TEXT), screen_width: window.screen.width, screen_height: window.screen.height,
      window_width: window.innerWidth, window_height: window.innerHeight, refresh_hz: clock.hz,
      intended_s: trial.stimulus_frames / C.nominal_hz, recruitment_pid: who.recruitment_pid,
      study_id: who.study_id, session_id: who.session_id, started: session.state.started,
      protocol_sha256: C.protocol_sha256,
    };
    Object.keys(trial.factors).forEach(function (f) { row[f] = trial.factors[f]; });
    if (trial.break_before && C.breaks) {
      const s = screen(display);
      at(s, el("div", "appeal-text", C.breaks.text), 0.05);
      await waitKey(" ", C.breaks.min_s);
    }
    let img = null;
    let bitmaps = null;
    let preloadMs = null;
    if (trial.clip) { // every frame decoded into a bitmap before the trial's first screen
      const t0 = performance.now();
      bitmaps = await decodeClip(trial.clip);
      preloadMs = performance.now() - t0;
    } else {
      img = new Image();
      img.src = trial.image;
      await img.decode(); // never a frame before the face is decoded
    }
    const fixAfter = C.timing.fixation_position === "after";
    const fixFrames = trial.fixation_frames ? framesAt(trial.fixation_frames) : 0;
    if (C.fixation) row.fixation_frames = fixFrames || null;
    if (fixFrames && !fixAfter) {
      const fix = await show(function () { at(screen(display), el("div", "appeal-fixation", "+"), 0); }, fixFrames);
      row.fixation_onset_s = seconds(fix.onset);
    }
    let n;
    let stim;
    if (trial.clip) {
      const schedule = clipSchedule(trial.clip);
      const clipFlips = schedule.perFrame.reduce(function (a, b) { return a + b; }, 0);
      const hold = trial.clip.hold_flips > 0 ? Math.max(0, framesAt(trial.stimulus_frames) - clipFlips) : 0;
      n = clipFlips + hold;
      const played = await showClip(display, bitmaps, schedule, hold, trial.title);
      bitmaps.forEach(function (b) { b.close(); }); // freed as soon as the clip has been shown
      delete document.body.dataset.appealClipFrame;
      delete document.body.dataset.appealClipHold;
      Object.assign(row, clipColumns(trial.clip, schedule, played, preloadMs));
      stim = played;
    } else {
      n = framesAt(trial.stimulus_frames);
      stim = await show(function () {
        const s = screen(display);
        if (trial.title) at(s, el("div", "appeal-title", trial.title), 0.45);
        s.appendChild(sized(img, C.screen.stimulus_height, 0));
      }, n);
    }
    let after;
    if (fixFrames && fixAfter) {
      after = await show(function () { at(screen(display), el("div", "appeal-fixation", "+"), 0); }, fixFrames);
      row.fixation_onset_s = seconds(after.onset);
    } else if (trial.respond) {
      after = await show(function () { screen(display); }, 1);
    } else {
      after = await show(function () { screen(display); }, framesAt(trial.iti_frames || 0));
    }
    const period = 1000 / clock.hz;
    const edges = stim.flips.concat([after.onset]);
    let dropped = 0; // animation-frame intervals over 1.5 refresh periods while the stimulus was up
    for (let i = 1; i < edges.length; i++) if (edges[i] - edges[i - 1] > C.timing.drop_threshold * period) dropped += 1;
    Object.assign(row, {
      onset_frame: stim.onsetFrame, onset_s: seconds(stim.onset), offset_s: seconds(after.onset),
      duration_frames: n, shown_frames: stim.flips.length, shown_s: (after.onset - stim.onset) / 1000,
      dropped_frames: dropped,
    });
    if (trial.clip) row.clip_dropped_frames = dropped;
    if (C.timing.on_dropped_frames === "flag") {
      row.dropped_flag = (dropped > 0 || (row.clip_frame_errors || 0) > 0) ? 1 : 0;
      row.repeat_of = null;
    }
    if (trial.respond) await respond(display, trial, row);
    if (trial.respond && trial.iti_frames) await show(function () { screen(display); }, framesAt(trial.iti_frames));
    row.focus_losses = losses.focus;
    row.fullscreen_losses = losses.fullscreen;
    session.state.rows.push(row);
    save(who, session.state);
    return row;
  }

  // ------------------------------------------------------------------ the end
  function download(who) {
    const blob = new Blob([tsv(session.state.rows)], { type: "text/tab-separated-values" });
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob);
    a.download = fileName(who);
    a.id = "appeal-download";
    a.textContent = "Download the data file (" + fileName(who) + ")";
    return a;
  }

  async function send(who) {
    if (!C.data_url || session.state.sent) return null;
    try {
      const r = await fetch(C.data_url, {
        method: "POST", headers: { "Content-Type": "text/tab-separated-values", "X-Appeal-File": fileName(who) },
        body: tsv(session.state.rows),
      });
      if (r.ok) { session.state.sent = true; save(who, session.state); }
      return r.ok;
    } catch (e) {
      return false;
    }
  }

  async function finish(display, who) {
    session.state.complete = true;
    save(who, session.state);
    if (document.fullscreenElement && document.exitFullscreen) document.exitFullscreen().catch(function () {});
    display.innerHTML = "";
    const box = el("div", "appeal-end");
    box.innerHTML = C.end_text;
    display.appendChild(box);
    const a = download(who);
    box.appendChild(el("p")).appendChild(a);
    const sent = await send(who);
    if (sent === false) box.appendChild(el("p", "appeal-warning", "The data could not be sent: please download the file above and send it to the experimenter."));
    if (C.completion_code) box.appendChild(el("p", "appeal-code", "Your completion code: " + C.completion_code));
    if (sent !== false) a.click();
    if (C.completion_url) {
      const link = el("a", "appeal-completion", "Back to the recruitment site");
      link.href = C.completion_url;
      box.appendChild(el("p")).appendChild(link);
      window.setTimeout(function () { window.location.href = C.completion_url; }, 3000);
    }
    document.body.dataset.appealState = "complete";
  }

  function fail(message) {
    document.body.innerHTML = "";
    document.body.appendChild(el("p", "appeal-error", message));
    document.body.dataset.appealState = "error";
  }

  // ------------------------------------------------------------------ start
  async function start() {
    document.documentElement.style.setProperty("--appeal-bg", "rgb(" + Array(3).fill(Math.round(C.screen.background * 255)).join(",") + ")");
    document.documentElement.style.setProperty("--appeal-fg", "rgb(" + Array(3).fill(Math.round(C.screen.text_color * 255)).join(",") + ")");
    document.title = C.title;
    const who = assign();
    if (!who) {
      fail("This link lacks a participant id (…?participant=ID of letters and digits, at most 64, or PROLIFIC_PID from the recruitment site).");
      return;
    }
    const list = LISTS[who.slot];
    let state = load(who);
    if (state && (state.slot !== who.slot || state.rows.some(function (r, i) { return !list[i] || r.trial !== list[i].trial; }))) {
      fail("The data kept in this browser belong to another trial list; ask the experimenter.");
      return;
    }
    const resumed = !!(state && state.rows.length);
    if (!state) state = { slot: who.slot, seed: who.seed, rows: [], part: 0, started: new Date().toISOString() };
    state.part += 1;
    save(who, state);
    session = { who: who, state: state };
    clock.hz = await measureRefresh();
    clock.t0 = performance.now();
    window.requestAnimationFrame(countFrames);
    const jsPsych = initJsPsych({ display_element: "appeal-display" });
    const display = document.getElementById("appeal-display");
    if (state.complete) {
      await finish(display, who);
      return;
    }
    const todo = list.slice(state.rows.length);
    const timeline = [];
    const images = [];
    todo.forEach(function (t) { if (t.clip) images.push.apply(images, t.clip.frames); else images.push(t.image); });
    timeline.push({
      type: jsPsychPreload, images: Array.from(new Set(images)),
      message: "Loading the images …", show_progress_bar: true, continue_after_error: false,
      error_message: "The images could not be loaded; please reload the page.",
    });
    if (C.fullscreen) {
      timeline.push({ type: jsPsychFullscreen, fullscreen_mode: true, message: "<p>The study runs in full screen.</p>",
                      button_label: "Continue" });
    }
    const cont = "<p class=\"appeal-continue\">" + C.continue_text + "</p>";
    if (resumed) {
      timeline.push({ type: jsPsychHtmlKeyboardResponse, choices: [" "],
                      stimulus: "<div class=\"appeal-page\"><p>Welcome back. The study continues with trial " +
                        (state.rows.length + 1) + " of " + list.length + ".</p>" + cont + "</div>" });
    } else {
      C.instructions.forEach(function (page) {
        timeline.push({ type: jsPsychHtmlKeyboardResponse, choices: [" "],
                        stimulus: "<div class=\"appeal-page\">" + page + cont + "</div>" });
      });
    }
    todo.forEach(function (t) { timeline.push({ type: AppealTrialPlugin, spec: t }); });
    document.body.dataset.appealState = "running";
    await jsPsych.run(timeline);
    await finish(display, who);
  }

  window.addEventListener("load", start);
})();
