"""Check that numpy sorts correctly on this machine: the emulated machine of vcan-vm gives wrong
answers from numpy's AVX2 kernels (an argsort of 64 floats out of order; once a segmentation fault),
so CI runs the vcan stage with those kernels off (NPY_DISABLE_CPU_FEATURES) and this check first."""

import sys

import numpy as np
from numpy._core._multiarray_umath import __cpu_features__

rng = np.random.default_rng(0)
for n in (16, 64, 256, 1000):
    for _ in range(50):
        a = rng.standard_normal(n)
        if not (np.diff(a[np.argsort(a)]) >= 0).all() or not (np.diff(np.sort(a)) >= 0).all():
            on = [k for k, v in __cpu_features__.items() if v]
            sys.exit(f"numpy sorts {n} floats out of order on this machine (CPU features in use: {on})")
print("numpy sorts correctly here")
