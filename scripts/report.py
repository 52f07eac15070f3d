#!/usr/bin/python3
"""`flexopt report OUT`: the pictures of a finished run, in OUT/report/ (docs/output.md "Report").

  history.png  optimize: objective, constraints (their bounds dotted) and the largest design
               change against the iteration, the projection's beta stages marked;
  design.png   optimize: the final design (physical_density >= 0.5) from three viewpoints, and
               for a dynamic case the initial design above it;
  motion.png   a dynamic run: the mechanism (of the final design, for optimize) at 6 instants,
               coloured by the elastic displacement, with the sensors' time series below;
  index.html   one page with the pictures, the case, the responses' first and final values,
               the run's time split and links to the XDMF files.

The plots are drawn with matplotlib; the 3D pictures are rendered by ParaView (pvbatch, with
scripts/report_render.py) on the display, or on an Xvfb server of its own where there is none. If
rendering is impossible the report says why, on the terminal and in index.html, and still
writes the plots and the page. Usage: report.py OUT [--no-render]. Exit status 0 if the report
was written (rendering or not), 1 if OUT holds no summary.json of a run.
"""
import csv
import html
import json
import os
import select
import shutil
import subprocess
import sys
import tempfile
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SIZE = [640, 480]


def read_history(out):
    path = os.path.join(out, "history.csv")
    if not os.path.isfile(path):
        return None
    rows = list(csv.DictReader(open(path)))
    if not rows:
        return None
    cols = {k: [float(r[k]) for r in rows] for k in rows[0]}
    return cols



def beta_text(beta):
    """A stage's projection sharpness: a number, or with several design bodies (a map of each
    body's) one number when they agree, else "body β, ..."."""
    if not isinstance(beta, dict):
        return f"{beta:g}"
    values = set(beta.values())
    if len(values) == 1:
        return f"{values.pop():g}"
    return ", ".join(f"{b} {v:g}" for b, v in beta.items())

def plot_history(s, h, png):
    """Objective, constraints and max change against the iteration; beta stages marked."""
    it = h["iteration"]
    cons = [k for k in h if k not in ("iteration", "objective", "max_change") and not k.startswith("seconds")]
    n = 2 + (1 if cons else 0)
    fig, axes = plt.subplots(n, 1, figsize=(8, 2.4 * n), sharex=True)
    axes[0].plot(it, h["objective"], color="C0")
    axes[0].set_ylabel("objective")
    axes[0].set_title(f"{s.get('case', '')}: optimization history")
    if cons:
        bounds = s.get("constraint_bounds") or []
        for i, k in enumerate(cons):
            axes[1].plot(it, h[k], color=f"C{i + 1}", label=k)
            if i < len(bounds):  # the constraint's max, dotted in its colour
                axes[1].axhline(bounds[i], color=f"C{i + 1}", lw=0.8, ls=":")
        axes[1].set_ylabel("constraints")
        axes[1].legend(fontsize="small")
    axes[-1].semilogy(it, h["max_change"], color="C7")
    axes[-1].set_ylabel("max design change")
    axes[-1].set_xlabel("iteration")
    for st in s.get("beta_stages", [])[1:]:
        for ax in axes:
            ax.axvline(st["first_iteration"] - 0.5, color="k", lw=0.8, ls="--")
        axes[0].annotate(f"β = {beta_text(st['beta'])}", (st["first_iteration"], 1), xycoords=("data", "axes fraction"),
                         xytext=(2, -12), textcoords="offset points", fontsize="small")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)


class Display:
    """Where pvbatch draws: the session's display, or an Xvfb server of the report's own.

    Xvfb runs with -noreset: by default an X server resets itself when its last client
    disconnects, and pvbatch connects twice (its capability check, then the render window), so
    the second connection could arrive during that reset and be dropped ("bad X server
    connection"; 8 of 10 renders under a CPU load of 4 busy processes on 2 cores, 0 of 20 with
    -noreset; xvfb-run, used before, starts Xvfb without it). -displayfd makes the server pick a
    free display number itself and report it once it accepts connections."""

    def __init__(self):
        self.server = None
        self.name = os.environ.get("DISPLAY", "")
        self.why = ""
        if not shutil.which("pvbatch"):
            self.why = "pvbatch (ParaView) is not installed (scripts/install_deps.sh installs it)"
        elif not self.name and not shutil.which("Xvfb"):
            self.why = "no display and no Xvfb (apt-get install xvfb; scripts/install_deps.sh installs it)"

    def __enter__(self):
        if self.why or self.name:
            return self
        read, write = os.pipe()
        try:
            self.server = subprocess.Popen(
                ["Xvfb", "-displayfd", str(write), "-screen", "0", "1280x1024x24", "-nolisten", "tcp",
                 "-noreset"],
                pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        except OSError as e:
            self.why = f"Xvfb failed to start: {e}"
            return self
        finally:
            os.close(write)
        number = b""
        deadline = time.time() + 30
        while not number.endswith(b"\n") and time.time() < deadline:
            ready, _, _ = select.select([read], [], [], max(0.0, deadline - time.time()))
            chunk = os.read(read, 16) if ready else b""
            if not chunk:
                break
            number += chunk
        os.close(read)
        if number.strip().isdigit():
            self.name = ":" + number.strip().decode()
        else:
            self.why = "Xvfb did not report a display within 30 s"
        return self

    def __exit__(self, *exc):
        if self.server is not None:
            self.server.terminate()
            try:
                self.server.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.server.kill()
                self.server.wait()
        return False


def clean_env():
    """The environment without the MPI launcher's variables: pvbatch is an MPI program of its
    own, and the rank's variables would make it join the job that runs flexopt."""
    return {k: v for k, v in os.environ.items()
            if not k.startswith(("OMPI_", "PMIX_", "PMI_", "HYDRA_", "MPI_LOCALRANKID", "PRTE_"))}


def expected_pictures(jobs):
    return [job["png"].format(k=k) for job in jobs for k in range(len(job.get("views") or job.get("times")))]


def render(jobs, work):
    """Runs the jobs (report_render.py); returns (ok, message): ok when every picture exists."""
    path = os.path.join(work, "jobs.json")
    json.dump(jobs, open(path, "w"))
    with Display() as display:
        if display.why:
            return False, display.why
        env = dict(clean_env(), DISPLAY=display.name)
        try:
            p = subprocess.run(["pvbatch", os.path.join(HERE, "report_render.py"), path], env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
        except (OSError, subprocess.TimeoutExpired) as e:
            return False, f"pvbatch failed to run: {e}"
    missing = [f for f in expected_pictures(jobs) if not os.path.isfile(f)]
    if p.returncode == 0 and not missing:
        return True, ""
    lines = [ln.strip() for ln in p.stdout.splitlines() if "ERR|" in ln or "report_render:" in ln]
    lines = lines or [ln for ln in p.stdout.splitlines() if ln.strip() and "0x" not in ln][-4:]
    return False, "pvbatch failed (exit %d, %d of %d pictures missing): %s" % (
        p.returncode, len(missing), len(expected_pictures(jobs)), " | ".join(lines[-4:]))


def compose(pngs, titles, out_png, rows=1, below=None, title=None, panel=(3.2, 2.6), below_rows=1):
    """Puts rendered pictures side by side (rows x columns) with titles; `below`: a function
    drawing into an extra full-width axis underneath."""
    rows = rows if pngs else 0
    cols = max(1, (len(pngs) + rows - 1) // rows) if rows else 1
    extra = 1 if below else 0
    fig = plt.figure(figsize=(max(panel[0] * cols, 8), panel[1] * rows + 1.6 * below_rows * extra))
    grid = fig.add_gridspec(rows + extra, cols,
                            height_ratios=[panel[1]] * rows + ([1.6 * below_rows] * extra))
    for k, (png, t) in enumerate(zip(pngs, titles)):
        ax = fig.add_subplot(grid[k // cols, k % cols])
        ax.imshow(mpimg.imread(png))
        ax.set_title(t, fontsize="small")
        ax.axis("off")
    if below:
        below(fig, grid[rows, :])
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out_png, dpi=110)
    plt.close(fig)


def motion_times(s, key):
    """Six instants spread over the motion's frames (the first and the last included)."""
    m = s.get(key, {}).get("motion") if key else s.get("motion")
    times = (m or {}).get("times") or []
    if not times:
        return []
    idx = sorted({round(k * (len(times) - 1) / 5) for k in range(6)})
    return [times[i] for i in idx]


def sensor_plot(s, times, key):
    """Draws every sensor on an axis of its own (positions and elastic displacements differ by
    orders of magnitude), its non-zero components, the pictures' instants marked."""
    sensors = (s.get(key, {}) if key else s).get("sensors", {})
    shown = [(n, v) for n, v in sensors.items() if v.get("t") and v.get("value")][:4]

    def draw(fig, spec):
        grid = spec.subgridspec(max(len(shown), 1), 1, hspace=0.08)
        for row, (name, v) in enumerate(shown):
            ax = fig.add_subplot(grid[row, 0])
            t, val = v["t"], v["value"]
            if isinstance(val[0], list):
                for c in range(len(val[0])):
                    comp = [r[c] for r in val]
                    if max(abs(x) for x in comp) > 0:
                        ax.plot(t, comp, label=f"{'xyz'[c] if len(val[0]) == 3 else c}")
            else:
                ax.plot(t, val)
            for tt in times:
                ax.axvline(tt, color="k", lw=0.6, ls=":")
            ax.set_ylabel(f"{name}\n({v.get('quantity', '')})", fontsize="small")
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize="x-small", loc="upper right")
            ax.grid(alpha=0.3)
            if row + 1 < len(shown):
                ax.tick_params(labelbottom=False)
            else:
                ax.set_xlabel("t [s]")
    return draw, max(len(shown), 1)


def fmt(v):
    return f"{v:.6g}" if isinstance(v, (int, float)) else html.escape(str(v))


def responses_rows(s, h):
    """(name, first, final) of the objective and every constraint (optimize), or the responses
    of a dynamic run."""
    rows = []
    if h:
        names = [k for k in h if k not in ("iteration", "max_change") and not k.startswith("seconds")]
        for k in names:
            rows.append((k, h[k][0], h[k][-1]))
    elif isinstance(s.get("responses"), dict):
        for k, v in s["responses"].items():
            rows.append((k, v, v))
    return rows


def time_rows(s):
    rows = []
    split = s.get("seconds_split")
    if isinstance(split, dict):
        for k, v in split.items():
            vals = [x for x in v if isinstance(x, (int, float))]
            rows.append((k, sum(vals)))
    for k in ("integration_s", "plan_s"):
        if isinstance(s.get(k), (int, float)):
            rows.append((k[:-2], s[k]))
    if isinstance(s.get("wall_s"), (int, float)):
        rows.append(("wall (the whole run)", s["wall_s"]))
    return rows


def write_index(out, rep, s, h, pictures, note):
    links = [f for f in sorted(os.listdir(out)) if f.endswith(".xdmf")]
    title = f"flexopt {html.escape(str(s.get('command', '')))}: {html.escape(str(s.get('case', '')))}"
    parts = [f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{title}</title>",
             "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto}"
             "img{max-width:100%;border:1px solid #ccc}td,th{padding:2px 10px;text-align:right}"
             "td:first-child,th:first-child{text-align:left}.note{color:#a40}</style></head><body>",
             f"<h1>{title}</h1>",
             f"<p>{s.get('ranks', '?')} rank(s); "
             + (f"{s.get('iterations')} iterations, stopped: {html.escape(str(s.get('stop_reason', '')))}"
                if "iterations" in s else f"{s.get('steps', '?')} steps of {s.get('time_step', '?')} s")
             + "</p>"]
    if note:
        parts.append(f"<p class='note'>{html.escape(note)}</p>")
    rows = responses_rows(s, h)
    if rows:
        parts.append("<h2>Responses</h2><table><tr><th>response</th><th>first</th><th>final</th></tr>")
        parts += [f"<tr><td>{html.escape(n)}</td><td>{fmt(a)}</td><td>{fmt(b)}</td></tr>" for n, a, b in rows]
        parts.append("</table>")
    for png, caption in pictures:
        parts.append(f"<h2>{html.escape(caption)}</h2><p><img src='{png}' alt='{html.escape(caption)}'></p>")
    rows = time_rows(s)
    if rows:
        parts.append("<h2>Time</h2><table><tr><th>part</th><th>seconds</th></tr>")
        parts += [f"<tr><td>{html.escape(n)}</td><td>{v:.2f}</td></tr>" for n, v in rows]
        parts.append("</table>")
    if links:
        parts.append("<h2>Files (open in ParaView)</h2><ul>")
        parts += [f"<li><a href='../{html.escape(f)}'>{html.escape(f)}</a></li>" for f in links]
        parts.append("</ul>")
    # For a browser check of the page (tests/check_report.py): how many pictures loaded.
    parts.append("<script>window.addEventListener('load', () => { const i = [...document.images]; "
                 "document.body.setAttribute('data-images-loaded', "
                 "i.filter(x => x.complete && x.naturalWidth > 0).length + '/' + i.length); });</script>")
    parts.append("</body></html>\n")
    open(os.path.join(rep, "index.html"), "w").write("\n".join(parts))


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if len(args) != 1:
        sys.exit("usage: report.py OUT [--no-render]")
    out = os.path.abspath(args[0])
    try:
        s = json.load(open(os.path.join(out, "summary.json")))
    except (OSError, ValueError) as e:
        print(f"report: {out}: no readable summary.json of a run ({e})", file=sys.stderr)
        sys.exit(1)
    rep = os.path.join(out, "report")
    os.makedirs(rep, exist_ok=True)
    h = read_history(out)
    pictures, jobs, notes = [], [], []
    if h:
        plot_history(s, h, os.path.join(rep, "history.png"))
        pictures.append(("history.png", "Optimization history"))
    work = tempfile.mkdtemp(prefix="flexopt_report_")
    design = os.path.join(out, "design.xdmf")
    scenario = None
    if "scenario_motions" in s and s["scenario_motions"]:
        # Scenarios: the first scenario's motions stand for the run's (each has its own files).
        scenario = next(iter(s["scenario_motions"]))
        s = dict(s, motion_final=s["scenario_motions"][scenario]["motion_final"])
    dynamic = s.get("analysis") == "dynamic" or "motion_final" in s
    if os.path.isfile(design):
        for which in (["first", "last"] if dynamic else ["last"]):
            jobs.append({"xdmf": design, "views": ["iso", "top", "front"], "time": which,
                         "threshold": "physical_density", "size": SIZE,
                         "png": os.path.join(work, f"design_{which}_{{k}}.png")})
    motion_key = "motion_final" if "motion_final" in s else None
    motion = os.path.join(out, ("motion_final" + (f".{scenario}" if scenario else "") + ".xdmf")
                          if motion_key else "motion.xdmf")
    times = motion_times(s, motion_key) if os.path.isfile(motion) else []
    if times:
        jobs.append({"xdmf": motion, "times": times, "view": "top", "threshold": "physical_density",
                     "color": "elastic_displacement", "size": [800, 450],
                     "png": os.path.join(work, "motion_{k}.png")})
    rendered, why = (False, "--no-render") if "--no-render" in sys.argv or not jobs else render(jobs, work)
    if jobs and not rendered:
        notes.append(f"3D pictures not rendered: {why}")
    if rendered and os.path.isfile(design):
        rows = ["first", "last"] if dynamic else ["last"]
        pngs = [os.path.join(work, f"design_{w}_{k}.png") for w in rows for k in range(3)]
        titles = [f"{'initial' if w == 'first' else 'final'} design, {v}" for w in rows
                  for v in ("iso", "top (x-y)", "front (x-z)")]
        compose(pngs, titles, os.path.join(rep, "design.png"), rows=len(rows),
                title="physical density >= 0.5")
        pictures.append(("design.png", "Design"))
    if times and (rendered or (s.get(motion_key, {}) if motion_key else s).get("sensors")):
        pngs = [os.path.join(work, f"motion_{k}.png") for k in range(len(times))] if rendered else []
        draw, nsensors = sensor_plot(s, times, motion_key)
        compose(pngs, [f"t = {t:.4g} s" for t in times[:len(pngs)]], os.path.join(rep, "motion.png"),
                rows=2, below=draw, title=("the final design moving" + (f" (scenario {scenario})" if scenario else ""))
                if motion_key else "the motion",
                panel=(4.6, 2.8), below_rows=nsensors)
        pictures.append(("motion.png", "Motion" + (" (colour: elastic displacement)" if rendered else "")))
    note = "; ".join(notes)
    write_index(out, rep, s, h, pictures, note)
    shutil.rmtree(work, ignore_errors=True)
    print(f"report: {rep}/index.html ({', '.join(p for p, _ in pictures) or 'no pictures'})"
          + (f"; {note}" if note else ""))


main()
