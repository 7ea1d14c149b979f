"""Source of ``peak_mib()`` for the subprocesses of the memory tests: the process's own peak resident memory.

``VmHWM`` of /proc/self/status (Linux), not ``resource.getrusage(...).ru_maxrss``: after a fork and exec
the latter also holds the parent's resident size at the fork (a pytest process that earlier slow tests had
made 600 MiB large reported 609 MiB for an identify run whose own peak was 311 MiB), so a measurement
launched from a large test process measured the test process.
"""

import textwrap

PEAK_MIB = textwrap.dedent(
    """
    def peak_mib():
        try:
            with open("/proc/self/status") as fh:
                return next(float(line.split()[1]) for line in fh if line.startswith("VmHWM:")) / 1024.0
        except (OSError, StopIteration):
            import resource
            return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    """
)
