"""Cheap calls for the hottest loops: inlined copies of kernels, and views
of arrays that carry no reference count.

A call from one numba kernel to another that takes the BVH or the surface
tables passes each of their arrays field by field (the BVH's five arrays
are about 45 machine words, the surface tables about 150) and counts a
reference to each array up at entry and down at exit: atomic operations on
memory every thread shares. Where such calls happen several times per path
vertex, that costs more than the work (bench/pathtrace.py shows it). Two
remedies, for the few loops where it matters:

- `inlined(kernel)`: a copy of the kernel that numba inlines at each call
  site (its IR, before LLVM), so nothing is passed and the counts cancel.
  Each call site compiles a copy, so the kernels themselves stay ordinary
  functions and a hot loop calls the copy from one site.
- `borrowed(x)`: the same array (or tuple of arrays, e.g. a `BVHArrays`)
  with no owner attached, so numba's reference counting skips it (it
  checks for a missing owner before every count). A kernel borrows its
  arguments at entry and uses the views inside; the caller keeps the
  owners alive for the whole call, so the views never outlive the data.
  Never return a borrowed view or store it where it outlives the call.
"""
from numba import config, njit, types
from numba.core import cgutils
from numba.extending import intrinsic


def inlined(kernel):
    """A copy of njit `kernel` that numba inlines at each call site (same
    options, not cached on its own: it compiles as part of its caller)."""
    options = {k: v for k, v in kernel.targetoptions.items() if k not in ("cache", "nopython")}  # njit implies nopython
    options["inline"] = "always"
    return njit(**options)(kernel.py_func)


def _borrow(context, builder, ty, value):
    """LLVM value of type ty with every array in it stripped of its owner
    (meminfo) and of its Python parent; other values pass unchanged (with
    the new reference the caller expects)."""
    if isinstance(ty, types.Array):
        src = context.make_array(ty)(context, builder, value=value)
        view = context.make_array(ty)(context, builder)
        for field in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(view, field, getattr(src, field))
        view.meminfo = cgutils.get_null_value(view.meminfo.type)
        view.parent = cgutils.get_null_value(view.parent.type)
        return view._getvalue()
    if isinstance(ty, types.BaseTuple):
        out = cgutils.get_null_value(context.get_value_type(ty))
        for i, member in enumerate(ty.types):
            out = builder.insert_value(out, _borrow(context, builder, member, builder.extract_value(value, i)), i)
        return out
    context.nrt.incref(builder, ty, value)
    return value


@intrinsic
def _borrowed(typingctx, x):
    """x (an array, or a tuple or namedtuple holding arrays) as views of the
    same memory that no reference count touches. Valid while the caller
    holds x."""
    def codegen(context, builder, signature, args):
        return _borrow(context, builder, signature.args[0], args[0])
    return x(x), codegen


def _itself(x):
    return x


borrowed = _itself if config.DISABLE_JIT else _borrowed  # kernels run as Python (NUMBA_DISABLE_JIT=1): x itself
