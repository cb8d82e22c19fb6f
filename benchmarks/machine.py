"""What machine a figure was measured on: CPU model, cores and vector extensions.

The same compiled kernels differ several-fold between machines (AVX2 and AVX-512 vector
widths, core counts), so every benchmark prints this beside its figures.
"""

import os
import platform


def machine() -> dict:
    """CPU model, logical CPUs and SIMD extensions (from /proc/cpuinfo where present)."""
    model, flags = platform.processor() or platform.machine(), set()
    try:
        with open("/proc/cpuinfo") as info:
            for line in info:
                key, _, value = line.partition(":")
                if key.strip() == "model name" and model in ("", platform.machine()):
                    model = value.strip()
                elif key.strip() == "flags":
                    flags = set(value.split())
                    break
    except OSError:
        pass
    known = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512vl")
    simd = [f for f in known if f in flags]
    return {"cpu": model, "logical_cpus": os.cpu_count(), "simd": simd}
