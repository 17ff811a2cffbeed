#!/usr/bin/env python3
"""Exits 0 when every test that failed in a ctest log (run with --output-on-failure) failed only
because LeakSanitizer's own stop-the-world tracer crashed at exit after the test had passed
("Tracer caught signal 11 ... LeakSanitizer has encountered a fatal error", an intermittent
crash of the sanitizer runtime, google/sanitizers#1353), and 1 otherwise (any other failure, a
leak report, a failed assertion, a timeout, or no failure at all)."""
import re
import sys


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: lsan_tracer_crashes_only.py CTEST_LOG")
    text = open(sys.argv[1], errors="replace").read()
    failed = [m for m in re.finditer(
        r"^\s*\d+/\d+ Test\s+#\d+: (\S+) \.+\s*\*\*\*(\w+)", text, re.M)
        if m.group(2) != "Skipped"]
    if not failed:
        print("no failed test in the log")
        return 1
    # Each failed test's output follows its result line, up to the next "Start" line.
    for m in failed:
        name, kind = m.group(1), m.group(2)
        end = text.find("        Start ", m.end())
        output = text[m.end():end if end >= 0 else len(text)]
        tracer = ("Tracer caught signal" in output
                  and "LeakSanitizer has encountered a fatal error" in output)
        passed = "[  PASSED  ]" in output and "[  FAILED  ]" not in output
        leak = "ERROR: LeakSanitizer: detected memory leaks" in output
        if kind != "Failed" or not tracer or not passed or leak:
            print("%s: a real failure (%s)" % (name, kind))
            return 1
        print("%s: passed, then LeakSanitizer's tracer crashed at exit" % name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
