"""A software prefetch hint for numba kernels (LLVM's llvm.prefetch).

`prefetch(arr, i)` asks the CPU to bring row i of a C-contiguous array
into cache; it has no effect on results. The propagation sweep uses it to
fetch the line-table entries, waiting records and sums a few cells ahead:
at a million voxels those are cache misses, and hiding them is most of the
difference between the small and the large scenes (bench/propagation.py).
"""
from llvmlite import ir
from numba import config, types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def _llvm_prefetch(typingctx, arr, idx):
    if not isinstance(arr, types.Array) or not isinstance(idx, types.Integer):
        return None
    sig = types.void(arr, idx)

    def codegen(context, builder, sig, args):
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        stride = builder.extract_value(ary.strides, 0)
        i = args[1]
        if i.type.width < stride.type.width:
            i = builder.sext(i, stride.type)
        elif i.type.width > stride.type.width:
            i = builder.trunc(i, stride.type)
        addr = builder.add(builder.ptrtoint(ary.data, stride.type), builder.mul(i, stride))
        i8p = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]),
                                            "llvm.prefetch.p0i8")
        # write intent (the rows are updated), high temporal locality, data cache
        builder.call(fn, [builder.inttoptr(addr, i8p), ir.Constant(i32, 1), ir.Constant(i32, 3), ir.Constant(i32, 1)])
        return context.get_dummy_value()
    return sig, codegen



def _no_prefetch(arr, idx):
    return None


# kernels run as Python (NUMBA_DISABLE_JIT=1: tests/test_clauses.py): a hint has nothing to do there
prefetch = _no_prefetch if config.DISABLE_JIT else _llvm_prefetch
