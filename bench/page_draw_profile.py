"""Where one drawing of the live page goes with software WebGL: every WebGL draw call and upload
of a few drawn frames, each timed on its own.

    python bench/page_draw_profile.py [--frames 6] [--warmup 8] [--calls] [-- serve options...]

``serve.py`` runs as in ``bench/bench_page.py`` (default options unless given after ``--``);
Debian's chromium (1400x900, SwiftShader) opens the page with a script that wraps the WebGL2
context: after the warmup it follows ``--frames`` drawn frames and times each draw call
(``drawArrays``/``drawElements``/instanced), buffer or texture upload and shader compile on its
own: from a 1-pixel ``readPixels`` before it to one after it, less the time of two readPixels in
a row (WebGL's ``finish()`` is only a flush in Chromium). Prints per frame the shader programs
(viser's materials: ``LineMaterial`` for line segments, ``MeshStandardMaterial`` for boxes and
meshes, ``MeshBasicMaterial [map]`` for images, ``ShaderMaterial [background]`` for viser's
full-window background quad) sorted by time, with their calls and vertices x instances;
``--calls``: every call of the first frame in order.

Waiting after every call serialises what the browser normally pipelines, and each wait ends the
renderer's pass over the (multisampled) framebuffer, so each call also carries a fixed cost of a
few milliseconds (read it off the ``clear`` line): the sum is larger than a frame's real cost,
compare large differences only. Wall-clock times: on a loaded machine they grow with the load.
"""

from __future__ import annotations

import argparse

from tileviz.testing.browser import ARGS, CHROMIUM
from tileviz.testing.wsclient import start_serve, stop_serve

HOOK = r"""
(() => {
  const P = window.__prof = {on: false, frames: [], cur: null, names: new Map(), next: 1};
  const tag = (src) => {
    const keys = [["cellSize", "grid"], ["linewidth", "line"], ["colorMap", "background"],
                  ["point_ball_norm", "points"], ["#define USE_MAP", "map"],
                  ["#define USE_INSTANCING", "instanced"],
                  ["#define USE_COLOR", "vertexcolor"], ["#define FLAT_SHADED", "flat"],
                  ["#define DOUBLE_SIDED", "double"]];
    const hit = keys.filter(([k]) => src.includes(k)).map(([, v]) => v);
    const m = src.match(/#define SHADER_(?:TYPE|NAME) (\S+)/g) || [];
    const t = m.map((x) => x.split(" ")[2]).join("/");
    return (t || "?") + (hit.length ? " [" + hit.join("+") + "]" : "");
  };
  const proto = WebGL2RenderingContext.prototype;
  const shaderSrc = new WeakMap(), progName = new WeakMap(), progId = new WeakMap();
  const origSource = proto.shaderSource;
  proto.shaderSource = function (sh, src) {
    shaderSrc.set(sh, src);
    return origSource.call(this, sh, src);
  };
  const origAttach = proto.attachShader;
  proto.attachShader = function (prog, sh) {
    const s = shaderSrc.get(sh) || "";
    if (s.includes("gl_FragColor") || s.includes("pc_fragColor") || s.includes("void main")) {
      const old = progName.get(prog) || "";
      progName.set(prog, old + " " + s);
    }
    return origAttach.call(this, prog, sh);
  };
  let current = null;
  const origUse = proto.useProgram;
  proto.useProgram = function (prog) { current = prog; return origUse.call(this, prog); };
  const name = (prog) => {
    if (!prog) return "none";
    if (!progId.has(prog)) progId.set(prog, P.next++);
    return "#" + progId.get(prog) + " " + tag(progName.get(prog) || "");
  };
  const px = new Uint8Array(16);
  const origRead = proto.readPixels;
  // WebGL's finish() is only a flush in Chromium: a 1-pixel readPixels waits for the drawing.
  const sync = (gl) => {
    const b = gl.getParameter(gl.PIXEL_PACK_BUFFER_BINDING);
    if (b) gl.bindBuffer(gl.PIXEL_PACK_BUFFER, null);
    origRead.call(gl, 0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    if (b) gl.bindBuffer(gl.PIXEL_PACK_BUFFER, b);
  };
  const timed = (fn, label, amount) => function (...a) {
    if (!P.on || !P.cur) return fn.apply(this, a);
    sync(this);
    const t0 = performance.now();
    sync(this);
    const t1 = performance.now();
    const r = fn.apply(this, a);
    sync(this);
    P.cur.push([label(a), amount(a), Math.max(0, performance.now() - t1 - (t1 - t0))]);
    return r;
  };
  const bytes = (x) => (x && x.byteLength) || 0;
  proto.drawArrays = timed(proto.drawArrays, () => name(current), (a) => a[2]);
  proto.drawElements = timed(proto.drawElements, () => name(current), (a) => a[1]);
  proto.drawArraysInstanced = timed(proto.drawArraysInstanced, () => name(current),
                                    (a) => a[2] * a[3]);
  proto.drawElementsInstanced = timed(proto.drawElementsInstanced, () => name(current),
                                      (a) => a[1] * a[4]);
  proto.bufferData = timed(proto.bufferData, () => "upload: bufferData", (a) => bytes(a[1]));
  proto.bufferSubData = timed(proto.bufferSubData, () => "upload: bufferSubData",
                              (a) => bytes(a[2]));
  proto.texImage2D = timed(proto.texImage2D, () => "upload: texImage2D",
                           (a) => (a.length > 6 ? a[3] * a[4]
                                                 : (a[5].width || 0) * (a[5].height || 0)));
  proto.texSubImage2D = timed(proto.texSubImage2D, () => "upload: texSubImage2D",
                              (a) => (a.length > 7 ? a[4] * a[5] : 0));
  proto.generateMipmap = timed(proto.generateMipmap, () => "upload: generateMipmap", () => 0);
  proto.linkProgram = timed(proto.linkProgram, () => "compile: linkProgram", () => 0);
  proto.compileShader = timed(proto.compileShader, () => "compile: compileShader", () => 0);
  proto.getProgramParameter = timed(proto.getProgramParameter,
                                    () => "compile: getProgramParameter", () => 0);
  proto.clear = timed(proto.clear, () => "clear", () => 0);
  proto.blitFramebuffer = timed(proto.blitFramebuffer, () => "blitFramebuffer (MSAA resolve)",
                                () => 0);
  window.__profStart = (n) => new Promise((done) => {
    P.on = true;
    P.frames = [];
    P.cur = null;
    const tick = () => {
      if (P.cur) P.frames.push(P.cur);
      if (P.frames.length >= n) { P.on = false; P.cur = null; done(P.frames); return; }
      P.cur = [];
      requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
  });
})();
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--warmup", type=float, default=8.0)
    ap.add_argument("--calls", action="store_true", help="also list the first frame's calls")
    ap.add_argument("--url", default=None, help="profile this page instead of starting serve.py")
    ap.add_argument("serve", nargs="*", help="serve.py options (after --)")
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    proc = None
    url = args.url
    if url is None:
        proc, url = start_serve(["--port", "0", *args.serve])
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.add_init_script(HOOK)
            page.goto(url)
            page.wait_for_selector("canvas", timeout=120_000)
            page.wait_for_timeout(args.warmup * 1000)
            frames = page.evaluate(f"window.__profStart({args.frames + 1})")
            size = page.evaluate(
                "(() => { const c = [...document.querySelectorAll('canvas')]"
                ".sort((a, b) => b.width * b.height - a.width * a.height)[0];"
                " return [c.width, c.height, window.devicePixelRatio]; })()")
            browser.close()
    finally:
        if proc is not None:
            stop_serve(proc)
    print(f"canvas {size[0]}x{size[1]} pixels, devicePixelRatio {size[2]}")
    for k, frame in enumerate(frames[1:]):
        total = sum(r[2] for r in frame)
        by: dict[str, list[float]] = {}
        for label, amount, ms in frame:
            row = by.setdefault(label, [0, 0, 0.0])
            row[0] += 1
            row[1] += amount
            row[2] += ms
        print(f"frame {k}: {len(frame)} calls, {total:.1f} ms with a finish after each")
        for label, (n, amount, ms) in sorted(by.items(), key=lambda kv: -kv[1][2]):
            if ms >= 0.2:
                print(f"  {ms:7.1f} ms  {n:4d} calls  {amount:9d}  {label}")
    if args.calls:
        for label, amount, ms in frames[1]:
            print(f"  call {ms:7.2f} ms  {amount:9d}  {label}")


if __name__ == "__main__":
    main()
