"""``compiled_helper``: the decorator of a numba kernel that only other compiled kernels call.

For every compiled function numba builds an entry point that Python can call (unboxing the
arguments, boxing the result, raising errors) and one that C code can call. A helper that
only other kernels call uses neither, and building them costs about a quarter of the first
run's compile time of the kernels they serve (docs/benchmarks.md), so ``compiled_helper``
compiles (on first use by a caller, kept in numba's on-disk cache like ``numba.njit(
cache=True)``) without them. Calling such a helper from Python crashes the interpreter:
``tests/stack/test_compiled_helpers.py`` checks that only compiled code refers to one.
A function that Python calls too is a helper all the same, with a small ``numba.njit(cache=
True)`` kernel for the Python callers (named after it, ``_<helper>_entry``, e.g.
``input_limits._fill_input_bounds_entry``; ``safety_rows._rows_entry`` serves three), which
is compiled only when Python calls it: a run's kernels then compile no entry points and no
machine code for it (docs/benchmarks.md, "The first run", "Seventh round").

A helper's code is also only ever run as part of its callers: numba links the LLVM code of
every function a kernel calls into the kernel's own library, optimizes that whole library
and generates its machine code, and the cache keeps each entry kernel whole (a warm run
loads no helper). So a helper's own library (``_LinkOnlyLibrary``) is neither optimized as
a whole nor turned into machine code, work that every library above it did again: its
functions are optimized one by one as numba lowers them, and the entry kernel's library
optimizes everything it links, as before (docs/benchmarks.md, "The first run", "Sixth
round": the people's kernels 12.2-13.3 -> 10.2-10.7 CPU s, the same trajectories). Its cache
entry keeps the LLVM code (numba's bitcode form), which is all a caller links. A helper's
numba environment (Python objects for boxing, which none of ours use) stays unset, as a
warm run leaves it anyway.
"""

import numba
from numba.core import codegen
from numba.core.compiler import CompilerBase, DefaultPassBuilder
from numba.core.compiler_machinery import LoweringPass, register_pass
from numba.core.typed_passes import AnnotateTypes


class _LinkOnlyLibrary(codegen.JITCodeLibrary):
    """numba's code library for a helper: finalizing it leaves its LLVM module ready to be
    linked into callers, without optimizing it as a whole or generating machine code."""

    def _optimize_final_module(self):
        """Nothing: the callers' libraries optimize the code they link in."""

    def _finalize_final_module(self):
        self._finalize_dynamic_globals()
        self._verify_declare_only_symbols()
        self._finalized = True

    @property
    def codegen(self):
        return _NoEnvironment(self._codegen)

    def serialize_using_object_code(self):
        """The cache entry: the library's LLVM code (there is no machine code)."""
        return self.serialize_using_bitcode()


class _NoEnvironment:
    """numba's code generator, except that a helper's environment is not set: its symbol is
    in no machine code (numba sets it as it makes the Python entry point, which a helper
    does not have)."""

    def __init__(self, generator):
        self._generator = generator

    def set_env(self, env_name, env):
        """Nothing (see the class docstring)."""

    def __getattr__(self, name):
        return getattr(self._generator, name)


@register_pass(mutates_CFG=False, analysis_only=False)
class _LinkOnly(LoweringPass):
    """Gives the function being compiled a ``_LinkOnlyLibrary`` before numba lowers it."""

    _name = "mrta_drake_link_only_library"

    def __init__(self):
        LoweringPass.__init__(self)

    def run_pass(self, state):
        state.library = _LinkOnlyLibrary(state.targetctx.codegen(), state.func_id.func_qualname)
        state.library.enable_object_caching()
        return False


class _HelperCompiler(CompilerBase):
    """numba's nopython pipeline with ``_LinkOnly`` before the lowering."""

    def define_pipelines(self):
        pipeline = DefaultPassBuilder.define_nopython_pipeline(self.state)
        pipeline.add_pass_after(_LinkOnly, AnnotateTypes)
        pipeline.finalize()
        return [pipeline]


# numba's options of a helper, but for the cache.
HELPER_OPTIONS = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True,
                  "pipeline_class": _HelperCompiler}
compiled_helper = numba.njit(cache=True, **HELPER_OPTIONS)
