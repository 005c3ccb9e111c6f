"""geotrajd started for a Python interop test: on 127.0.0.1:0, its output in a file (a pipe
that nobody reads could fill and block it) whose first line tells the address."""
import re
import subprocess
import time


def start_geotrajd(server, log_path, extra_args=(), env=None):
    """Returns (process, address, log) once geotrajd says where it serves; RuntimeError with
    its output when it does not within 30 s."""
    log = open(log_path, "w+")
    proc = subprocess.Popen([server, "--address", "127.0.0.1:0", *extra_args], env=env, stdout=log,
                            stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and proc.poll() is None:
        log.seek(0)
        m = re.search(r"^geotrajd: serving .* on (\S+:\d+)", log.read(), re.M)
        if m:
            return proc, m.group(1), log
        time.sleep(0.05)
    proc.kill()
    proc.wait()
    log.seek(0)
    raise RuntimeError(f"geotrajd did not report its address: {log.read()}")
