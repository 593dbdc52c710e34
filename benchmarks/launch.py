"""Run one command and write its wall time and resource usage as JSON: `python -S launch.py REPORT CMD...`.

Why a launcher: on Linux a process's peak RSS (`ru_maxrss`) carries over the high-water mark of the
memory image it replaced at exec, and a child that the benchmark parent starts directly begins as the
parent's image (fork/vfork). A child of a parent holding 2 GB would therefore report a 2 GB peak however
little it used. This launcher is a small interpreter that imports only the standard library (~10 MB).
It starts the measured command itself and reaps it with `os.wait4`, so the figures are the command's own.
Only the standard library, and `-S` (no site): keep it small.
"""

import json
import os
import sys
import time


def main() -> int:
    report_path, command = sys.argv[1], sys.argv[2:]
    start = time.perf_counter()
    pid = os.posix_spawnp(command[0], command, os.environ)
    _, status, usage = os.wait4(pid, 0)
    wall_s = time.perf_counter() - start
    code = os.waitstatus_to_exitcode(status)
    with open(report_path, "w") as report:
        json.dump({"wall_s": wall_s, "max_rss_kb": usage.ru_maxrss, "user_s": usage.ru_utime,
                   "system_s": usage.ru_stime, "exit_code": code}, report)
    return code if code >= 0 else 128 - code


if __name__ == "__main__":
    sys.exit(main())
