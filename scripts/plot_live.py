#!/usr/bin/env python3
"""Draws live execution and jogging as measured through a real geotrajd (docs/live.md).

Usage: plot_live.py GEOTRAJD [--stubs DIR] [--out DIR] [--plan REQUEST.json] [--stops]
  GEOTRAJD   the server binary (build/server/geotrajd); started on a free loopback port
  --stubs    the Python stubs (default build/tests/interop/pystubs)
  --out      where the figures go (default docs/figures)
  --plan     the plan to execute (default client/grpcurl/plan_panda_path_c.json)
  --stops    also stop the plan at several times and reserves and print the predicted
             against the measured stopping time and plan time (docs/live.md's table)

Three runs through the Python client, each written as a self-contained SVG:
  live_override.svg  Execute, speed override 40 % at t = 1 s and 100 % at t = 2.5 s
  live_pause.svg     Execute, pause at t = 1 s, resume 1 s after the motion is at rest
  jog_limit.svg      Jog, the Panda's joint 4 jogged at full speed into its upper limit
Commands are sent when the first sample at or after the time arrives (the server paces
samples in real time, so sample time is the call's clock); a thread sends a heartbeat every
0.2 s (the deadman time is 1 s). The Python standard library, grpcio and matplotlib (the
figures, by scripts/geotraj_plot.py) are used; every curve is decimated to the minimum and
maximum of each bucket (peaks kept) so that the files stay small.
"""
import argparse
import os
import queue
import subprocess
import socket
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import geotraj_plot as gp  # noqa: E402

COLOURS = gp.COLOURS
BUCKETS = 240     # min/max buckets per curve

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))


# --- the server and the calls ------------------------------------------------------------------

def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_geotrajd(server):
    """As tests/interop/test_python_client.py: geotrajd on a free port and a ready channel."""
    import grpc
    port = free_port()
    proc = subprocess.Popen([server, "--address", f"127.0.0.1:{port}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    channel = grpc.insecure_channel(f"127.0.0.1:{port}")
    grpc.channel_ready_future(channel).result(timeout=30)
    return proc, channel


def stop_geotrajd(proc, channel):
    channel.close()
    proc.terminate()
    proc.wait(timeout=30)


class LiveCall:
    """One Execute or Jog call: the first message, then control messages from send() and a
    heartbeat every 0.2 s until the server ends the call."""

    def __init__(self, method, first, heartbeat):
        self.outbox = queue.Queue()
        self.done = threading.Event()
        self.heartbeat = heartbeat
        self.outbox.put(first)
        self.call = method(self.requests())
        threading.Thread(target=self.beat, daemon=True).start()

    def requests(self):
        while True:
            message = self.outbox.get()
            if message is None:
                return
            yield message

    def beat(self):
        while not self.done.wait(0.2):
            self.outbox.put(self.heartbeat)

    def send(self, message):
        self.outbox.put(message)

    def batches(self):
        """(samples, status) per batch, until the server ends the call (see ending())."""
        import grpc
        try:
            for batch in self.call:
                yield batch.samples, batch.live
        except grpc.RpcError:
            pass
        finally:
            self.done.set()
            self.outbox.put(None)

    def ending(self):
        """The call's status code name and its trailer geotraj-stop-reason ("" without one)."""
        reason = dict(self.call.trailing_metadata() or ()).get("geotraj-stop-reason", "")
        return self.call.code().name, reason


class Record:
    """The samples of one live call as columns, and the status of each batch."""

    def __init__(self):
        self.t, self.tau, self.r, self.q, self.qd, self.qdd = [], [], [], [], [], []
        self.status = []  # (t of the batch's last sample, LiveStatus)
        self.details = ""  # the status message the call ended with

    def add(self, s):
        self.t.append(s.t)
        self.tau.append(s.plan_time)
        self.r.append(s.speed_factor)
        self.q.append(list(s.joints))
        self.qd.append(list(s.joint_velocities))
        self.qdd.append(list(s.joint_accelerations))

    def column(self, rows, j):
        return [row[j] for row in rows]


def execute(pb, stub, plan, script, reserve=None):
    """Runs `plan` live; script(sample, status, call, record) is called for every sample (status:
    the LiveStatus of the batch before, None at first) and may send commands. Returns the record
    and (code name, trailer reason)."""
    options = pb.ExecuteOptions()
    if reserve is not None:
        options.acceleration_reserve = reserve
    call = LiveCall(stub.Execute, pb.ExecuteRequest(plan=plan, options=options),
                    pb.ExecuteRequest(heartbeat=pb.Heartbeat()))
    record = Record()
    status = None
    for samples, live in call.batches():
        for s in samples:
            record.add(s)
            script(s, status, call, record)
        status = live
        record.status.append((record.t[-1] if record.t else 0.0, live))
    record.details = call.call.details()
    return record, call.ending()


def limits_of(pb, stub, name):
    for m in stub.ListRobots(pb.ListRobotsRequest()).robots:
        if m.name == name:
            return list(m.limits)
    raise SystemExit(f"no robot {name} on the server")


def binding_joint(status):
    """The joint that binds the speed factor's acceleration: its zero-based index and its name
    as LiveStatus.binding gives it ("joint 2 (panda_joint2)": numbered from 1 there)."""
    name = status.binding.split(",")[0].replace(" acceleration", "")
    words = name.split()
    if len(words) > 1 and words[0] == "joint":
        return int(words[1]) - 1, name
    return 0, "joint 1"


def slowing_start(record, after):
    """The time the speed factor started to fall from its steady value after `after` [s]:
    the sample before the first one below it (the profile starts from that sample's state)."""
    for k in range(1, len(record.t)):
        if record.t[k] > after and record.r[k] < record.r[k - 1]:
            return k - 1
    return None


def first_rest(record, after):
    for k in range(len(record.t)):
        if record.t[k] > after and record.r[k] == 0.0:
            return k
    return None


# --- figures (scripts/geotraj_plot.py) -----------------------------------------------------

def dash_style(dash):
    """An SVG dash array ("5,3") as a matplotlib line style."""
    if not dash:
        return "-"
    return (0, tuple(float(v) for v in dash.replace(" ", ",").split(",") if v))


class Figure:
    """Panels stacked over one time axis; `notes`: lines of text under the title. Collects the
    panels, then draws them with geotraj_plot.stacked_figure on write()."""

    def __init__(self, title, x_range, panels, notes=()):
        self.title, self.x_range, self.notes = title, x_range, list(notes)
        self.panels = [None] * panels

    def panel(self, i, title, y_label, series, y_range=None, hlines=(), vlines=(), x_label=False, x_range=None):
        """series: (label, colour, points, dash or None); hlines: (y, label), the limits (a label
        that names a limit) drawn red with an id limit-<panel>-<k>; vlines: (x, label, colour)."""
        drawn = []
        for label, colour, points, dash in series:
            xs, ys = zip(*points) if points else ((), ())
            drawn.append({"x": xs, "y": ys, "label": label or None, "colour": colour, "ls": dash_style(dash),
                          "lw": 1.4, "decimate": False})
        limits = []
        last_label = ""
        for k, (y, label) in enumerate(hlines):
            # An unlabelled line right after a labelled one is its mirror (the lower limit).
            named = label or last_label
            is_limit = "limit" in named
            limits.append({"y": y, "label": label or None, "colour": gp.LIMIT_RED if is_limit else "#555555",
                           "gid": f"limit-{i}-{k}" if is_limit else None, "ls": (0, (6, 3))})
            last_label = label or last_label
        x0, x1 = x_range if x_range else self.x_range
        marks = [{"x": x, "label": label or None, "colour": colour, "ls": (0, (3, 2))}
                 for x, label, colour in vlines if x0 <= x <= x1]
        self.panels[i] = {"series": drawn, "limits": limits, "vlines": marks, "title": title, "ylabel": y_label,
                          "ylim": y_range and (y_range[0] - 0.06 * (y_range[1] - y_range[0]),
                                               y_range[1] + 0.06 * (y_range[1] - y_range[0])),
                          "xlim": x_range, "xlabel": "time t [s]" if (x_label or x_range) else None}

    def write(self, path):
        fig, _ = gp.stacked_figure(self.title, self.panels, notes=self.notes, xlim=self.x_range, width=10.0,
                                   panel_height=2.1)
        gp.save(fig, path)
        print(f"wrote {os.path.relpath(path, ROOT)} ({os.path.getsize(path) // 1024} kB)")


def pts(xs, ys):
    """The curve reduced to the minimum and maximum of BUCKETS buckets (peaks kept)."""
    x, y = gp.decimate(xs, ys, BUCKETS)
    return list(zip(x.tolist(), y.tolist()))


# --- the three runs ----------------------------------------------------------------------------

def run_override(pb, stub, plan, limits, out):
    sent = {}

    def script(s, status, call, record):
        if "40" not in sent and s.t >= 1.0:
            call.send(pb.ExecuteRequest(speed_override=40))
            sent["40"] = s.t
        if "100" not in sent and s.t >= 2.5:
            call.send(pb.ExecuteRequest(speed_override=100))
            sent["100"] = s.t

    rec, (code, reason) = execute(pb, stub, plan, script)
    first = rec.status[0][1]
    j, joint_name = binding_joint(first)
    lim = limits[j]
    t_end = rec.t[-1]
    print(f"override: {len(rec.t)} samples, ended at t = {t_end:.3f} s (plan {first.plan_duration_s:.3f} s), "
          f"{code} / {reason}; bounds at full speed |dr/dt| <= {first.factor_acceleration_limit:.4g} 1/s, "
          f"|d2r/dt2| <= {first.factor_jerk_limit:.4g} 1/s^2 ({first.binding})")
    usage_v = max(abs(row[k]) / limits[k].max_velocity for row in rec.qd for k in range(len(row)))
    usage_a = max(abs(row[k]) / limits[k].max_acceleration for row in rec.qdd for k in range(len(row)))
    print(f"  largest joint velocity / limit {usage_v:.3f}, acceleration / limit {usage_a:.3f}")
    command = [(0.0, 1.0), (sent["40"], 1.0), (sent["40"], 0.4), (sent["100"], 0.4), (sent["100"], 1.0), (t_end, 1.0)]
    notes = [f"client/grpcurl/plan_panda_path_c.json (accelerationReserve 0.1); override 40 % sent at t = "
             f"{sent['40']:.3f} s, 100 % at t = {sent['100']:.3f} s; ended {code}, trailer reason {reason}",
             f"speed factor bounds at full speed: |dr/dt| \u2264 {first.factor_acceleration_limit:.3g} /s "
             f"({first.binding.split(',')[0]}), |d\u00b2r/dt\u00b2| \u2264 {first.factor_jerk_limit:.4g} /s\u00b2; "
             f"largest |q\u0307|/limit {usage_v:.3f}, |q\u0308|/limit {usage_a:.3f} over all joints"]
    fig = Figure(f"Execute with a speed override: Panda, path C, {len(rec.t)} samples at 1 kHz", (0.0, t_end), 4,
                 notes)
    marks = [(sent["40"], "", "#888"), (sent["100"], "", "#888")]  # the commands, unlabelled
    fig.panel(0, "speed factor r = d\u03c4/dt", "r [1]",
              [("r (streamed speed_factor)", COLOURS[0], pts(rec.t, rec.r), None),
               ("override command", "#888", command, "5,3")], y_range=(0.0, 1.0), vlines=marks)
    fig.panel(1, "plan time \u03c4 (where on the plan)", "\u03c4 [s]",
              [("\u03c4 live", COLOURS[0], pts(rec.t, rec.tau), None),
               ("\u03c4 = t (as planned)", "#888", [(0.0, 0.0), (first.plan_duration_s,) * 2], "5,3")],
              hlines=[(first.plan_duration_s, "end of plan")], vlines=marks)
    fig.panel(2, f"{joint_name} velocity (the joint that binds |dr/dt|)", "rad/s",
              [(joint_name.split(" (")[0], COLOURS[1], pts(rec.t, rec.column(rec.qd, j)), None)],
              hlines=[(lim.max_velocity, "limit"), (-lim.max_velocity, "")], vlines=marks)
    fig.panel(3, f"{joint_name} acceleration", "rad/s\u00b2",
              [(joint_name.split(" (")[0], COLOURS[1], pts(rec.t, rec.column(rec.qdd, j)), None)],
              hlines=[(lim.max_acceleration, "limit"), (-lim.max_acceleration, "")], vlines=marks, x_label=True)
    fig.write(os.path.join(out, "live_override.svg"))


def run_pause(pb, stub, plan, limits, out):
    sent = {}

    def script(s, status, call, record):
        if "pause" not in sent and s.t >= 1.0:
            call.send(pb.ExecuteRequest(pause=pb.Pause()))
            sent["pause"] = s.t
            sent["predicted"] = status.stopping_time_s
            sent["predicted_tau"] = status.stopping_plan_time_s
        if "pause" in sent and "rest" not in sent and s.speed_factor == 0.0 and s.t > sent["pause"]:
            sent["rest"] = s.t
        if "rest" in sent and "resume" not in sent and s.t >= sent["rest"] + 1.0:
            call.send(pb.ExecuteRequest(resume=pb.Resume()))
            sent["resume"] = s.t

    rec, (code, reason) = execute(pb, stub, plan, script)
    first = rec.status[0][1]
    j, joint_name = binding_joint(first)
    lim = limits[j]
    k0 = slowing_start(rec, sent["pause"] - 1e-9)
    k1 = first_rest(rec, sent["pause"])
    t0, t1 = rec.t[k0], rec.t[k1]
    predicted_rest = t0 + sent["predicted"]
    print(f"pause: sent at t = {sent['pause']:.3f} s, slowing from t = {t0:.3f} s, at rest at t = {t1:.3f} s: "
          f"{t1 - t0:.3f} s and {rec.tau[k1] - rec.tau[k0]:.3f} s of plan time, predicted at most "
          f"{sent['predicted']:.3f} s and {sent['predicted_tau']:.3f} s; resumed at t = {sent['resume']:.3f} s; "
          f"{code} / {reason}")
    t_end = rec.t[-1]
    notes = [f"client/grpcurl/plan_panda_path_c.json (accelerationReserve 0.1); pause sent at t = "
             f"{sent['pause']:.3f} s, resume at t = {sent['resume']:.3f} s; ended {code}, trailer reason {reason}",
             f"at rest {t1 - t0:.3f} s after slowing began, having covered {rec.tau[k1] - rec.tau[k0]:.3f} s of plan "
             f"time; the bound streamed before the pause: T_stop \u2264 {sent['predicted']:.3f} s, "
             f"plan time \u2264 {sent['predicted_tau']:.3f} s"]
    fig = Figure(f"Execute, pause and resume: Panda, path C, {len(rec.t)} samples at 1 kHz", (0.0, t_end), 4,
                 notes)
    marks = [(sent["pause"], "pause sent", "#888"), (t1, "at rest", COLOURS[2]),
             (predicted_rest, "at rest by the bound T_stop", COLOURS[3]), (sent["resume"], "resume sent", "#444")]
    fig.panel(0, "speed factor r", "r [1]", [("r", COLOURS[0], pts(rec.t, rec.r), None)], y_range=(0.0, 1.0),
              vlines=marks)
    fig.panel(1, "plan time \u03c4", "\u03c4 [s]", [("\u03c4 live", COLOURS[0], pts(rec.t, rec.tau), None)],
              hlines=[(rec.tau[k0] + sent["predicted_tau"], "\u03c4 when slowing began + the bound r T_stop / 2"),
                      (first.plan_duration_s, "end of plan")], vlines=marks)
    fig.panel(2, f"{joint_name} velocity", "rad/s",
              [(joint_name.split(" (")[0], COLOURS[1], pts(rec.t, rec.column(rec.qd, j)), None)],
              hlines=[(lim.max_velocity, "limit"), (-lim.max_velocity, "")], vlines=marks)
    fig.panel(3, f"{joint_name} acceleration", "rad/s\u00b2",
              [(joint_name.split(" (")[0], COLOURS[1], pts(rec.t, rec.column(rec.qdd, j)), None)],
              hlines=[(lim.max_acceleration, "limit"), (-lim.max_acceleration, "")], vlines=marks, x_label=True)
    fig.write(os.path.join(out, "live_pause.svg"))


def run_jog(pb, stub, limits, out):
    joint = 3  # index 3, panda_joint4: home -2.356 rad, upper limit -0.0698 rad
    lim = limits[joint]
    start = pb.JogStart(robot=pb.RobotSpec(name="panda"), cycle_rate_hz=1000, velocity_scale=1.0)
    call = LiveCall(stub.Jog, pb.JogRequest(start=start), pb.JogRequest(heartbeat=pb.Heartbeat()))
    command = [0.0] * 7
    command[joint] = 1.0
    call.send(pb.JogRequest(joints=pb.JointJog(velocities=command)))
    rec = Record()
    rested, stopped = None, False  # when a batch first ended at rest on the limit; Stop sent
    for samples, live in call.batches():
        for s in samples:
            rec.add(s)
        if rested is None and joint in live.limited_joints and rec.qd[-1][joint] == 0.0:
            rested = rec.t[-1]
        if rested is not None and not stopped and rec.t[-1] >= rested + 0.3:
            call.send(pb.JogRequest(stop=pb.Stop()))
            stopped = True
    code, reason = call.ending()
    q = rec.column(rec.q, joint)
    k_peak = max(range(len(q)), key=lambda k: q[k])
    top = max(r[joint] for r in rec.qd)
    k_brake = next(k for k in range(1, len(rec.t)) if rec.qd[k][joint] < rec.qd[k - 1][joint] == top)
    held = rec.t[next(k for k in range(k_brake, len(rec.t)) if rec.qd[k][joint] == 0.0)]  # first at rest
    print(f"jog: panda_joint{joint + 1} from {q[0]:.4f} rad to {q[-1]:.6f} rad (limit {lim.max_position} rad, "
          f"largest {q[k_peak]:.9f}); braking from t = {rec.t[k_brake]:.3f} s, at rest on the limit at "
          f"t = {held:.3f} s; {len(rec.t)} samples; {code} / {reason}")
    t_end = rec.t[-1]
    notes = [f"JogStart: robot panda from home, cycleRateHz 1000, velocityScale 1 (command 1 = {lim.max_velocity} "
             f"rad/s); joints command (0, 0, 0, 1, 0, 0, 0); Stop 0.3 s after rest; ended {code}, "
             f"trailer reason {reason}",
             f"braking starts at t = {rec.t[k_brake]:.3f} s, at rest at t = {held:.3f} s at q = {q[k_peak]:.9f} rad "
             f"(limit {lim.max_position} rad): the largest q of the {len(rec.t)} samples is {q[k_peak]:.9f}"]
    fig = Figure(f"Jog: the Panda's panda_joint{joint + 1} (index {joint}) at full speed into its upper limit, 1 kHz",
                 (0.0, t_end), 4, notes)
    marks = [(rec.t[k_brake], "braking starts", "#888"), (held, "at rest on the limit", COLOURS[2])]
    fig.panel(0, f"panda_joint{joint + 1} position", "rad", [(f"q{joint}", COLOURS[0], pts(rec.t, q), None)],
              hlines=[(lim.max_position, "upper limit")], vlines=marks)
    fig.panel(1, f"panda_joint{joint + 1} velocity", "rad/s",
              [(f"q\u0307{joint}", COLOURS[0], pts(rec.t, rec.column(rec.qd, joint)), None)],
              hlines=[(lim.max_velocity, "limit"), (-lim.max_velocity, "")], vlines=marks)
    fig.panel(2, f"panda_joint{joint + 1} acceleration (jerk \u2264 {lim.max_jerk:g} rad/s\u00b3)", "rad/s\u00b2",
              [(f"q\u0308{joint}", COLOURS[0], pts(rec.t, rec.column(rec.qdd, joint)), None)],
              hlines=[(lim.max_acceleration, "limit"), (-lim.max_acceleration, "")], vlines=marks)
    # The last stretch, close up: how far from the limit, never below zero.
    lo, hi = rec.t[k_brake] - 0.03, held + 0.05
    near = [k for k in range(len(rec.t)) if lo <= rec.t[k] <= hi]
    fig.panel(3, f"distance to the upper limit, t from {lo:.2f} to {hi:.2f} s (close up)", "mrad",
              [("q_max \u2212 q", COLOURS[0], [(rec.t[k], 1e3 * (lim.max_position - q[k])) for k in near], None)],
              hlines=[(0.0, "limit")], vlines=marks, x_label=True, x_range=(lo, hi))
    fig.write(os.path.join(out, "jog_limit.svg"))


def run_stops(pb, stub, plans):
    """Stops from full speed at several times: the bound against the measured stop."""
    print("\n| plan | reserve | stop sent at t [s] | predicted T_stop [s] | measured [s] | predicted plan time [s] "
          "| measured [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name, plan, times, reserves in plans:
        for reserve in reserves:
            for at in times:
                sent = {}

                def script(s, status, call, record, at=at):
                    if "stop" not in sent and s.t >= at:
                        call.send(pb.ExecuteRequest(stop=pb.Stop()))
                        sent["stop"] = s.t
                        sent["T"] = status.stopping_time_s
                        sent["tau"] = status.stopping_plan_time_s

                rec, (code, reason) = execute(pb, stub, plan, script, reserve)
                k0 = slowing_start(rec, sent["stop"] - 1e-9) if "stop" in sent else None
                if k0 is None or reason != "stopped":
                    print(f"| {name} | {reserve} | {at} | (ended {code} {reason} before: {rec.details}) | | | |")
                    continue
                k1 = len(rec.t) - 1
                print(f"| {name} | {reserve} | {sent['stop']:.3f} | {sent['T']:.3f} | {rec.t[k1] - rec.t[k0]:.3f} | "
                      f"{sent['tau']:.3f} | {rec.tau[k1] - rec.tau[k0]:.3f} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("server")
    parser.add_argument("--stubs", default=os.path.join(ROOT, "build/tests/interop/pystubs"))
    parser.add_argument("--out", default=os.path.join(ROOT, "docs/figures"))
    parser.add_argument("--plan", default=os.path.join(ROOT, "client/grpcurl/plan_panda_path_c.json"))
    parser.add_argument("--stops", action="store_true")
    args = parser.parse_args()
    sys.path.insert(0, args.stubs)
    from google.protobuf import json_format
    from geotraj.v1 import geotraj_pb2 as pb
    from geotraj.v1 import geotraj_pb2_grpc as rpc

    with open(args.plan) as f:
        plan = json_format.Parse(f.read(), pb.PlanRequest())
    proc, channel = start_geotrajd(args.server)
    try:
        stub = rpc.TrajectoryServiceStub(channel)
        limits = limits_of(pb, stub, plan.robot.name or "panda")
        os.makedirs(args.out, exist_ok=True)
        run_override(pb, stub, plan, limits, args.out)
        run_pause(pb, stub, plan, limits, args.out)
        run_jog(pb, stub, limits_of(pb, stub, "panda"), args.out)
        if args.stops:
            with open(os.path.join(ROOT, "client/grpcurl/plan_pa10_path_c.json")) as f:
                pa10 = json_format.Parse(f.read(), pb.PlanRequest())
            pa10.robot.report_only = False  # Execute keeps the limits: it refuses reportOnly
            pa10.motion.duration_s = 0.0      # time-optimal (its 10 s trapezoid breaks the limits)
            slow = pb.PlanRequest()
            slow.CopyFrom(pa10)
            slow.motion.duration_s = 20.0     # a durationS keeps its room: the reserve does not apply
            run_stops(pb, stub, [("Panda path C, time-optimal", plan, (0.5, 1.0, 2.0), (0.1, 0.3, 0.5)),
                                 ("PA-10 path C, time-optimal", pa10, (1.0, 3.0), (0.1, 0.3)),
                                 ("PA-10 path C, 20 s trapezoid", slow, (4.0, 10.0), (0.1,))])
    finally:
        stop_geotrajd(proc, channel)


if __name__ == "__main__":
    main()
