"""``compiled_helper``: the decorator of a numba kernel that only other compiled kernels call.

For every compiled function numba builds an entry point that Python can call (unboxing the
arguments, boxing the result, raising errors) and one that C code can call. A helper that
only other kernels call uses neither, and building them costs about a quarter of the first
run's compile time of the kernels they serve (docs/benchmarks.md), so ``compiled_helper``
compiles (on first use by a caller, kept in numba's on-disk cache like ``numba.njit(
cache=True)``) without them. Calling such a helper from Python crashes the interpreter:
``tests/stack/test_compiled_helpers.py`` checks that only compiled code refers to one.
"""

import numba

compiled_helper = numba.njit(cache=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)
