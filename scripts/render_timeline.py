"""Prints (does not assert) a timeline of one F12 render on the add-on's workers started ahead: where a
render's wall time goes outside the units' tracing (docs/performance.md "A render's fixed cost").

  .venv/bin/python scripts/render_timeline.py [--files cornell hdri] [--resolution 96] [--samples 64]
         [--repeats 2] [--events]

Per file: the sample .blend opened with bpy and exported as F12 exports it (outside the clock), the pool
F12 takes when the add-on started its workers ahead (mcrt_addon/bench_materials.py measured_warm_pool:
two viewport workers kept for one render, kernels loaded), then engine.api.render timed from its call to
its return.  The pool's messages are watched from Blender's side (engine/pools/viewport.py ViewportPool:
the scene sent, each worker's "ready" with its preparation's wall and CPU seconds, each unit sent and
answered with the unit's own seconds in the worker), and printed as marks in milliseconds since the
call:
  encode       the prepare message pickled (its size);
  ready w      worker w prepared the scene (its PreparedScene seconds, wall and CPU);
  units w      worker w's first unit sent .. last answered, the sum of its units' own seconds;
  idle w       worker w's time without a unit between its ready and the last answer (the tail);
  close        the pool shut down (its workers ended) .. render() returned.
The render's last renders are used (--repeats: the first is a warm-up whose page faults differ).
"""
import argparse
import dataclasses
import os
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if REPO not in sys.path:
    sys.path.insert(0, REPO)


def watched_render(exported, settings, threads):
    """One render on a warm pool with its pool's messages marked: (marks, stats)."""
    from mcrt_addon import bench_materials as bm, bridge
    viewport = bridge.module("pools.viewport")
    pool, _, workers_cpu = bm.measured_warm_pool(threads)
    inner = pool.inner
    marks = []
    t0 = [None]

    def mark(who, what, **extra):
        marks.append(dict(t=time.perf_counter() - t0[0], who=who, what=what, **extra))

    encode = viewport.encode

    def timed_encode(message, **options):
        start = time.perf_counter()
        data = encode(message, **options)
        if message and message[0] == "prepare":
            mark("parent", "encode", ms=1e3 * (time.perf_counter() - start), bytes=len(data))
        return data
    viewport.encode = timed_encode
    event = inner._event

    def watched_event(worker, ev):
        kind = ev[0]
        if kind == "ready":
            facts = ev[2]
            mark(worker.number, "ready", setup=facts.setup_seconds, setup_cpu=facts.setup_cpu_seconds,
                 build=facts.build_seconds)
        elif kind in ("result", "error"):
            result = ev[2] if kind == "result" else None
            mark(worker.number, "answer", unit=ev[1].index, seconds=getattr(result, "seconds", None))
        return event(worker, ev)
    inner._event = watched_event
    for w in inner.workers:
        send = w.send

        def watched_send(message, w=w, send=send):
            if isinstance(message, tuple) and message[0] == "unit":
                mark(w.number, "send", unit=message[1].index)
            return send(message)
        w.send = watched_send
    close = inner.close

    def watched_close(**kw):
        mark("parent", "close")
        close(**kw)
        mark("parent", "closed")
    inner.close = watched_close
    render = bridge.render_function()
    t0[0] = time.perf_counter()
    try:
        result = render(exported.scene, settings, pool=pool, log=lambda *a, **k: None)
    finally:
        viewport.encode = encode
    mark("parent", "returned")
    stats = dict(result.stats, workers_cpu=workers_cpu["after"] - workers_cpu["before"])
    return marks, stats


def summary(marks):
    """The figures of one render's marks (module docstring), in ms."""
    at = {m["what"]: m["t"] for m in marks if m["who"] == "parent"}
    end = max(m["t"] for m in marks if m["what"] == "answer")
    out = dict(total=1e3 * at["returned"], encode=next(m["ms"] for m in marks if m["what"] == "encode"),
               bytes=next(m["bytes"] for m in marks if m["what"] == "encode"),
               last_answer=1e3 * end, close=1e3 * (at["closed"] - at["close"]),
               after_close=1e3 * (at["returned"] - at["closed"]), before_close=1e3 * (at["close"] - end))
    for w in sorted({m["who"] for m in marks if m["who"] != "parent"}):
        mine = [m for m in marks if m["who"] == w]
        ready = next((m for m in mine if m["what"] == "ready"), None)
        answers = [m for m in mine if m["what"] == "answer"]
        busy = sum(m["seconds"] or 0.0 for m in answers)
        out[f"w{w}"] = dict(ready=1e3 * ready["t"] if ready else None,
                            setup=1e3 * ready["setup"] if ready else None,
                            setup_cpu=1e3 * ready["setup_cpu"] if ready else None,
                            units=len(answers), busy=1e3 * busy,
                            last=1e3 * max((m["t"] for m in answers), default=0.0),
                            idle=1e3 * (end - (ready["t"] if ready else 0.0) - busy))
    return out


def print_marks(marks):
    for m in marks:
        extra = " ".join(f"{k}={v:.4f}" if isinstance(v, float) else f"{k}={v}" for k, v in m.items()
                         if k not in ("t", "who", "what"))
        print(f"  {1e3 * m['t']:8.1f} ms  {str(m['who']):>6}  {m['what']:<8} {extra}")


def print_summary(label, s):
    workers = [k for k in s if k.startswith("w")]
    print(f"{label}: total {s['total']:.0f} ms; encode {s['encode']:.1f} ms ({s['bytes'] / 1e3:.0f} kB); "
          f"last answer {s['last_answer']:.0f}; to close {s['before_close']:.1f}; close {s['close']:.1f}; "
          f"after {s['after_close']:.1f}")
    for k in workers:
        w = s[k]
        print(f"   {k}: ready {w['ready']:.0f} ms (setup {w['setup']:.0f} wall, {w['setup_cpu']:.0f} CPU); "
              f"{w['units']} units, {w['busy']:.0f} ms in them, last at {w['last']:.0f}; idle {w['idle']:.0f}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--files", nargs="+", default=["cornell"])
    p.add_argument("--resolution", type=int, default=96)
    p.add_argument("--samples", type=int, default=64)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--repeats", type=int, default=2, help="renders per file; the first is a warm-up")
    p.add_argument("--events", action="store_true", help="print every mark, not only the summary")
    args = p.parse_args(argv)
    sys.argv = sys.argv[:1]
    from mcrt_addon import bench_estimators as be
    sys.path.insert(0, REPO)
    import bench_sample_files as bsf           # noqa: F401 - the scripts' directory is on sys.path
    print(f"render_timeline: {time.strftime('%Y-%m-%d %H:%M:%S', time.gmtime())} UTC, load "
          f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}; {REPO}")
    for name in args.files:
        path = os.path.join(REPO, "sample_blends", name + ".blend")
        scene = be.open_blend(path, (args.resolution, args.resolution))
        settings = bsf.file_settings(scene, samples=args.samples, threads=args.threads)
        exported = be.export_tracer_scene(scene, (args.resolution, args.resolution))
        for r in range(args.repeats):
            marks, stats = watched_render(exported, dataclasses.replace(settings), args.threads)
            if r == 0 and args.repeats > 1:
                continue
            backends = set(stats.get("kernel_backends", {}).values())
            label = (f"{name} {args.resolution}^2 {args.samples} spp ({stats.get('units')} units, "
                     f"{'/'.join(sorted(backends))}; workers' CPU {stats['workers_cpu']:.2f} s), render {r}")
            print_summary(label, summary(marks))
            if args.events:
                print_marks(marks)
    print(f"load at the end {' '.join(f'{v:.2f}' for v in os.getloadavg())}, "
          f"{time.strftime('%H:%M:%S', time.gmtime())} UTC")
    return 0


if __name__ == "__main__":
    sys.exit(main())
