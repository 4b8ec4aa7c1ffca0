"""Silence what an SDK's C code prints past Python: some write banners and device probes to the process's file
descriptors 1 and 2 (pybullet's "build time" at import, Warp's "Could not find or load the NVIDIA CUDA driver" on a
machine without a GPU), which land in every worker's output, so that `run --quiet` is no longer quiet and a sweep's
stderr holds lines that are not ours."""
from __future__ import annotations

import ctypes
import os
import sys
from contextlib import contextmanager


@contextmanager
def native_output_silenced():
    """Descriptors 1 and 2 point at /dev/null meanwhile; C's buffers are flushed there before they are restored."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            os.dup2(null.fileno(), 2)
            try:
                yield
            finally:
                ctypes.CDLL(None).fflush(None)
    finally:
        for fd, copy in zip((1, 2), saved):
            os.dup2(copy, fd)
            os.close(copy)
