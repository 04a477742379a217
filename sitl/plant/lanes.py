"""Lanes: one quantity of W vehicles in one SIMD register, so that the control core's laws,
compiled once more with lanes where they take floats, fly W vehicles per instruction.

The laws of :mod:`companion.control` are written once for floats and for NumPy arrays of a
batch (:mod:`companion.control.vector`): branches on per-vehicle values go through ``where``,
``is_scalar`` picks the element-wise path. A :data:`lanes` value is that batch form in compiled
code: an LLVM ``<W x double>`` with ``+ - * /``, comparisons (giving a :data:`mask`), ``&``, ``|``,
``~`` and the element-wise helpers (``sqrt``, ``where``, ``minimum``, ``any_of``, ``all_of`` ... and
the functions marked :func:`~companion.control.jit.lanewise`, run lane by lane, such as the rare
rejections of the noise's ziggurat, ``rng.beyond_rectangle``). Integer lanes (the noise keys) have
int64 ``+ - * & | ^ >> <<`` and index a float64 table (``rng``'s layer edges), so the noise's
hashing and the ziggurat's first test run for W vehicles at once. Each lane computes
exactly what the float code computes: IEEE addition, multiplication, division and square root
round the same in a vector register as in a scalar one, comparisons and selects follow the float
forms of the helpers (``minimum(a, b) = a if a < b else b``), and the transcendental functions
(``sin``, ``cos``, ``atan2`` ...) are called lane by lane, the same libm as the float code. So a
vehicle flown in a lane of a batch flies bit for bit as it flies alone.

What the float code does with a per-vehicle value that a lane cannot do (``if x > 0.0:`` on a
lanes value) fails when the batch kernel compiles ("No implementation of function bool(mask)"),
never silently. Values that every vehicle of a batch shares (the time, the flight's schedule,
controller kinds) stay plain floats and integers, and ordinary branches on them are free.

- :data:`lanes`, :data:`int_lanes` (per-vehicle integers: the noise keys), :data:`mask`;
- :func:`load` / :func:`store`: W consecutive numbers of a row of a float64 array, as lanes;
- :func:`lane`: the k-th vehicle's value of any nested tuple (lanes become floats), so scalar
  code (a log row, a final position) runs on one vehicle of a lanes state;
- :func:`widener`: a state built from constants, with lanes where its step will put them;
- :func:`register`: installs all of it in numba (the batch kernel calls it before compiling).

Named tuples whose fields are floats in one place and lanes in another (a state built from
constants, then stepped) unify field by field (:func:`register` teaches numba that, which it
does for anonymous tuples only).
"""

from __future__ import annotations

import math
import operator
from typing import Any

from companion.control.jit import depends_on, float_forms, lanewise_functions

depends_on(__file__)

__all__ = ["W", "lanes", "int_lanes", "mask", "load", "load_int", "store", "lane", "widener", "register"]

W = 4
"""Vehicles per register: 4 doubles fill an AVX2 register (half an AVX-512 one; two SSE registers
where the CPU has no AVX; the same numbers everywhere). Measured on this project's machine
(docs/benchmarks.md, "Batches in lanes"), 4000 vehicles on one core: 4.6 M vehicle-steps/s with 4
lanes, 3.4 M with 8, 3.0 M with 16 (the wider the lanes, the more of a vehicle's state the laws
spill to the stack), against 2.05 M for vehicles one by one."""

_registered = False
lanes: Any = None
int_lanes: Any = None
mask: Any = None


def load(a: Any, j: int, i0: int) -> Any:  # pragma: no cover - replaced in compiled code
    """``a[j, i0:i0 + W]`` as lanes (compiled code only)."""
    raise NotImplementedError("lanes exist in compiled code only")


def load_int(a: Any, j: int, i0: int) -> Any:  # pragma: no cover
    """``a[j, i0:i0 + W]`` (integers held in float64) as integer lanes (compiled code only)."""
    raise NotImplementedError("lanes exist in compiled code only")


def store(a: Any, j: int, i0: int, x: Any) -> None:  # pragma: no cover
    """``a[j, i0:i0 + W] = x`` for lanes ``x`` or one number for all (compiled code only)."""
    raise NotImplementedError("lanes exist in compiled code only")


def lane(x: Any, k: int) -> Any:
    """Vehicle ``k``'s value of ``x``: lanes become floats, inside any nesting of tuples (interpreted,
    where there are no lanes, ``x`` is one vehicle's and is returned as it is)."""
    return x


_WIDENERS: list[tuple[Any, frozenset[str]]] = []


def widener(shared: frozenset[str]) -> Any:
    """``widen(x, like)``: ``x`` (nested tuples) with every float made lanes, but for the fields
    named in ``shared`` (a batch's common clock), when ``like`` is lanes; ``x`` itself otherwise.
    A state built from constants is widened to the types its step gives it, so the loop that
    carries it is typed once."""
    def widen(x: Any, like: Any) -> Any:
        return x

    _WIDENERS.append((widen, frozenset(shared)))
    if _registered:
        _define_widener(widen, frozenset(shared))
    return widen


def _define_widener(widen: Any, shared: frozenset[str]) -> None:
    from numba.core import cgutils, types
    from numba.core.typing.templates import signature
    from numba.extending import intrinsic, overload

    def wide(ty: Any, name: str | None) -> Any:
        if isinstance(ty, types.Float) and name not in shared:
            return lanes
        if isinstance(ty, types.BaseNamedTuple):
            return types.NamedTuple([wide(t, f) for t, f in zip(ty, ty.fields)], ty.instance_class)
        if isinstance(ty, types.BaseTuple):
            return types.Tuple([wide(t, None) for t in ty])
        return ty

    def cast(context: Any, builder: Any, ty: Any, to: Any, val: Any) -> Any:
        if isinstance(ty, types.BaseTuple) and ty != to:
            items = cgutils.unpack_tuple(builder, val, len(ty))
            return context.make_tuple(builder, to, [cast(context, builder, f, t, v)
                                                    for f, t, v in zip(ty, to, items)])
        return context.cast(builder, val, ty, to)

    @intrinsic
    def _wide(typingctx: Any, x: Any) -> Any:
        def lower(context: Any, builder: Any, sig: Any, args: Any) -> Any:
            return cast(context, builder, sig.args[0], sig.return_type, args[0])
        return signature(wide(x, None), x), lower

    @overload(widen, strict=False)
    def _widen(x: Any, like: Any) -> Any:
        if getattr(like, "lanes", False):
            return lambda x, like: _wide(x)
        return lambda x, like: x


def register() -> None:
    """Define the lanes types and their operations in numba (once per process)."""
    global _registered, lanes, int_lanes, mask
    if _registered:
        return
    _registered = True
    _define()
    for widen, shared in _WIDENERS:
        _define_widener(widen, shared)


def _define() -> None:  # noqa: C901 - one place for every numba definition of the lanes
    global lanes, int_lanes, mask
    from llvmlite import ir
    from numba.core import cgutils, types
    from numba.core.typeconv import Conversion
    from numba.core.typing.templates import AbstractTemplate, infer_global, signature
    from numba.extending import intrinsic, lower_builtin, lower_cast, models, overload, register_model

    f64, i64, i1, i32 = ir.DoubleType(), ir.IntType(64), ir.IntType(1), ir.IntType(32)
    vf64, vi64, vi1 = ir.VectorType(f64, W), ir.VectorType(i64, W), ir.VectorType(i1, W)

    def _number(t: Any) -> bool:
        return isinstance(t, (types.Float, types.Integer))

    class LanesType(types.Type):
        lanes = True

        def __init__(self) -> None:
            super().__init__(name=f"Lanes{W}")

        def can_convert_from(self, typingctx: Any, other: Any) -> Any:
            if _number(other):
                return Conversion.safe
            return None

        def unify(self, typingctx: Any, other: Any) -> Any:
            if _number(other):
                return self
            return None

    class IntLanesType(types.Type):
        lanes = True

        def __init__(self) -> None:
            super().__init__(name=f"IntLanes{W}")

    class MaskType(types.Type):
        lanes = True

        def __init__(self) -> None:
            super().__init__(name=f"Mask{W}")

        def can_convert_from(self, typingctx: Any, other: Any) -> Any:
            if isinstance(other, types.Boolean):
                return Conversion.safe
            return None

        def unify(self, typingctx: Any, other: Any) -> Any:
            if isinstance(other, types.Boolean):
                return self
            return None

    lanes, int_lanes, mask = LanesType(), IntLanesType(), MaskType()

    for cls, be in ((LanesType, vf64), (IntLanesType, vi64), (MaskType, vi1)):
        def model(dmm: Any, fe_type: Any, be: Any = be) -> Any:
            return models.PrimitiveModel(dmm, fe_type, be)
        register_model(cls)(model)

    def splat(builder: Any, x: Any) -> Any:
        vt = ir.VectorType(x.type, W)
        v = builder.insert_element(ir.Constant(vt, ir.Undefined), x, ir.Constant(i32, 0))
        return builder.shuffle_vector(v, ir.Constant(vt, ir.Undefined), ir.Constant(ir.VectorType(i32, W), [0] * W))

    @lower_cast(types.Float, LanesType)
    @lower_cast(types.Integer, LanesType)
    def _number_to_lanes(context: Any, builder: Any, fromty: Any, toty: Any, val: Any) -> Any:
        return splat(builder, context.cast(builder, val, fromty, types.float64))

    @lower_cast(types.Boolean, MaskType)
    def _bool_to_mask(context: Any, builder: Any, fromty: Any, toty: Any, val: Any) -> Any:
        return splat(builder, context.cast(builder, val, fromty, types.boolean))

    # --- named tuples unify field by field (numba does it for anonymous tuples only) ---
    def _unify_named(self: Any, typingctx: Any, other: Any) -> Any:
        if (isinstance(other, types.NamedTuple) and other.instance_class is self.instance_class
                and len(other) == len(self)):
            unified = [typingctx.unify_pairs(a, b) for a, b in zip(self.types, other.types)]
            if all(u is not None for u in unified):
                return types.NamedTuple(unified, self.instance_class)
        return None

    def _convert_named(self: Any, typingctx: Any, other: Any) -> Any:
        if (isinstance(other, types.NamedTuple) and other.instance_class is self.instance_class
                and len(other) == len(self)):
            kinds = [typingctx.can_convert(a, b) for a, b in zip(self.types, other.types)]
            if all(k is not None for k in kinds):
                return max(kinds)
        return None

    if "unify" not in types.NamedTuple.__dict__:
        types.NamedTuple.unify = _unify_named
    if "can_convert_to" not in types.NamedTuple.__dict__:
        types.NamedTuple.can_convert_to = _convert_named

    @lower_cast(types.NamedTuple, types.NamedTuple)
    def _named_to_named(context: Any, builder: Any, fromty: Any, toty: Any, val: Any) -> Any:
        items = cgutils.unpack_tuple(builder, val, len(fromty))
        return context.make_tuple(builder, toty,
                                  [context.cast(builder, v, f, t) for v, f, t in zip(items, fromty, toty)])

    # --- arithmetic and comparisons ---
    def _lanes_operands(args: tuple[Any, ...]) -> bool:
        """Float arithmetic on lanes: a float lanes operand, or integer lanes with a float (as
        numba computes ``int + float``: the integer converted first)."""
        return (all(isinstance(a, (LanesType, IntLanesType)) or _number(a) for a in args)
                and (any(isinstance(a, LanesType) for a in args)
                     or (any(isinstance(a, IntLanesType) for a in args)
                         and any(isinstance(a, types.Float) for a in args))))

    @lower_cast(IntLanesType, LanesType)
    def _int_lanes_to_lanes(context: Any, builder: Any, fromty: Any, toty: Any, val: Any) -> Any:
        return builder.sitofp(val, vf64)

    @lower_cast(types.Integer, IntLanesType)
    def _int_to_int_lanes(context: Any, builder: Any, fromty: Any, toty: Any, val: Any) -> Any:
        return splat(builder, context.cast(builder, val, fromty, types.int64))

    def _binary(op: Any, emit: Any, result: Any) -> None:
        class Template(AbstractTemplate):
            def generic(self, args: Any, kws: Any) -> Any:
                if len(args) == 2 and not kws and _lanes_operands(args):
                    return signature(result, lanes, lanes)
                return None

        infer_global(op)(Template)

        @lower_builtin(op, LanesType, LanesType)
        def impl(context: Any, builder: Any, sig: Any, args: Any) -> Any:
            return emit(builder, args[0], args[1])

    arith = (
        (operator.add, lambda b, x, y: b.fadd(x, y)),
        (operator.sub, lambda b, x, y: b.fsub(x, y)),
        (operator.mul, lambda b, x, y: b.fmul(x, y)),
        (operator.truediv, lambda b, x, y: b.fdiv(x, y)),
    )
    inplace = {operator.add: operator.iadd, operator.sub: operator.isub, operator.mul: operator.imul,
               operator.truediv: operator.itruediv}
    for op, emit in arith:
        _binary(op, emit, lanes)
        _binary(inplace[op], emit, lanes)
    # as numba compares floats: ordered, except != (true when either is NaN)
    for op, sym in ((operator.lt, "<"), (operator.le, "<="), (operator.gt, ">"), (operator.ge, ">="),
                    (operator.eq, "==")):
        _binary(op, lambda b, x, y, sym=sym: b.fcmp_ordered(sym, x, y), mask)
    _binary(operator.ne, lambda b, x, y: b.fcmp_unordered("!=", x, y), mask)

    class Unary(AbstractTemplate):
        def generic(self, args: Any, kws: Any) -> Any:
            if len(args) == 1 and isinstance(args[0], LanesType):
                return signature(lanes, lanes)
            return None

    infer_global(operator.neg)(Unary)
    infer_global(operator.pos)(Unary)
    infer_global(abs)(Unary)
    infer_global(round)(Unary)  # (the nearest integer, as lanes: the float forms' round() is rint)

    @lower_builtin(operator.neg, LanesType)
    def _neg(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return builder.fneg(args[0])

    @lower_builtin(operator.pos, LanesType)
    def _pos(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return args[0]

    def vector_intrinsic(builder: Any, name: str, *args: Any) -> Any:
        fnty = ir.FunctionType(vf64, [vf64] * len(args))
        fn = cgutils.get_or_insert_function(builder.module, fnty, f"llvm.{name}.v{W}f64")
        return builder.call(fn, args)

    @lower_builtin(abs, LanesType)
    def _abs(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return vector_intrinsic(builder, "fabs", args[0])

    @lower_builtin(round, LanesType)
    def _round(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return vector_intrinsic(builder, "rint", args[0])

    def _mask_operands(args: tuple[Any, ...]) -> bool:
        return (any(isinstance(a, MaskType) for a in args)
                and all(isinstance(a, (MaskType, types.Boolean)) for a in args))

    for op, name in ((operator.and_, "and_"), (operator.or_, "or_"), (operator.xor, "xor"),
                     (operator.iand, "and_"), (operator.ior, "or_"), (operator.ixor, "xor")):
        class MaskTemplate(AbstractTemplate):
            def generic(self, args: Any, kws: Any) -> Any:
                if len(args) == 2 and _mask_operands(args):
                    return signature(mask, mask, mask)
                return None

        infer_global(op)(MaskTemplate)

        @lower_builtin(op, MaskType, MaskType)
        def _mask_op(context: Any, builder: Any, sig: Any, args: Any, name: str = name) -> Any:
            return getattr(builder, name)(args[0], args[1])

    class Invert(AbstractTemplate):
        def generic(self, args: Any, kws: Any) -> Any:
            if len(args) == 1 and isinstance(args[0], MaskType):
                return signature(mask, mask)
            return None

    infer_global(operator.invert)(Invert)

    @lower_builtin(operator.invert, MaskType)
    def _invert(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return builder.not_(args[0])

    # --- integer lanes (the noise's hashing): int64 arithmetic as numba does it on int64 ---
    def _int_operands(args: tuple[Any, ...]) -> bool:
        return (len(args) == 2 and any(isinstance(a, IntLanesType) for a in args)
                and all(isinstance(a, (IntLanesType, types.Integer)) for a in args))

    for op, name in ((operator.add, "add"), (operator.sub, "sub"), (operator.mul, "mul"),
                     (operator.and_, "and_"), (operator.or_, "or_"), (operator.xor, "xor"),
                     (operator.rshift, "ashr"), (operator.lshift, "shl")):
        class IntTemplate(AbstractTemplate):
            def generic(self, args: Any, kws: Any) -> Any:
                if not kws and _int_operands(args):
                    return signature(int_lanes, int_lanes, int_lanes)
                return None

        infer_global(op)(IntTemplate)

        @lower_builtin(op, IntLanesType, IntLanesType)
        def _int_op(context: Any, builder: Any, sig: Any, args: Any, name: str = name) -> Any:
            return getattr(builder, name)(args[0], args[1])

    @overload(operator.getitem, strict=False)
    def _gather(a: Any, i: Any) -> Any:
        if (isinstance(a, types.Array) and a.ndim == 1 and a.dtype == types.float64
                and isinstance(i, IntLanesType)):
            return lambda a, i: _gather_lanes(a, i)
        return None

    @intrinsic
    def _gather_lanes(typingctx: Any, a: Any, i: Any) -> Any:
        """``a[i]`` for each lane's index (a table look-up: the ziggurat's layer edges)."""
        def lower(context: Any, builder: Any, sig: Any, args: Any) -> Any:
            arr = context.make_array(sig.args[0])(context, builder, args[0])
            out = ir.Constant(vf64, ir.Undefined)
            for k in range(W):
                idx = builder.extract_element(args[1], ir.Constant(i32, k))
                ptr = cgutils.get_item_pointer(context, builder, sig.args[0], arr, [idx])
                out = builder.insert_element(out, builder.load(ptr), ir.Constant(i32, k))
            return out
        return signature(lanes, a, int_lanes), lower

    class FloatOfLanes(AbstractTemplate):
        def generic(self, args: Any, kws: Any) -> Any:
            if len(args) == 1 and isinstance(args[0], LanesType):
                return signature(lanes, lanes)
            return None

    infer_global(float)(FloatOfLanes)

    @lower_builtin(float, LanesType)
    def _float_of_lanes(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return args[0]

    # --- the element-wise helpers of companion.control.vector, for lanes ---
    def as_lanes(context: Any, builder: Any, ty: Any, val: Any) -> Any:
        return context.cast(builder, val, ty, lanes)

    def as_mask(context: Any, builder: Any, ty: Any, val: Any) -> Any:
        return context.cast(builder, val, ty, mask)

    def select(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        (ct, at, bt), (c, a, b) = sig.args, args
        return builder.select(as_mask(context, builder, ct, c), as_lanes(context, builder, at, a),
                              as_lanes(context, builder, bt, b))

    def cmp(context: Any, builder: Any, sym: str, at: Any, a: Any, bt: Any, b: Any) -> Any:
        return builder.fcmp_ordered(sym, as_lanes(context, builder, at, a), as_lanes(context, builder, bt, b))

    def minimum(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        (at, bt), (a, b) = sig.args, args
        return builder.select(cmp(context, builder, "<", at, a, bt, b), as_lanes(context, builder, at, a),
                              as_lanes(context, builder, bt, b))

    def maximum(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        (at, bt), (a, b) = sig.args, args
        return builder.select(cmp(context, builder, ">", at, a, bt, b), as_lanes(context, builder, at, a),
                              as_lanes(context, builder, bt, b))

    def clip(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        (xt, lt, ht), (x, lo, hi) = sig.args, args
        xv, lv, hv = (as_lanes(context, builder, t, v) for t, v in ((xt, x), (lt, lo), (ht, hi)))
        inner = builder.select(builder.fcmp_ordered(">", xv, hv), hv, xv)
        return builder.select(builder.fcmp_ordered("<", xv, lv), lv, inner)

    def sqrt(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return vector_intrinsic(builder, "sqrt", as_lanes(context, builder, sig.args[0], args[0]))

    def absolute(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return vector_intrinsic(builder, "fabs", as_lanes(context, builder, sig.args[0], args[0]))

    def rint(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return vector_intrinsic(builder, "rint", as_lanes(context, builder, sig.args[0], args[0]))

    def any_of(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        m = as_mask(context, builder, sig.args[0], args[0])
        return builder.icmp_unsigned("!=", builder.bitcast(m, ir.IntType(W)), ir.Constant(ir.IntType(W), 0))

    def all_of(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        m = as_mask(context, builder, sig.args[0], args[0])
        ones = ir.Constant(ir.IntType(W), (1 << W) - 1)
        return builder.icmp_unsigned("==", builder.bitcast(m, ir.IntType(W)), ones)

    vector_forms = {"sqrt": sqrt, "absolute": absolute, "minimum": minimum, "maximum": maximum, "clip": clip,
                    "where": select, "rint": rint}

    def lane_value(builder: Any, ty: Any, val: Any, k: int) -> tuple[Any, Any]:
        """(scalar type, value) of lane k of ``val`` (a number is every lane's)."""
        if isinstance(ty, LanesType):
            return types.float64, builder.extract_element(val, ir.Constant(i32, k))
        if isinstance(ty, IntLanesType):
            return types.int64, builder.extract_element(val, ir.Constant(i32, k))
        if isinstance(ty, MaskType):
            return types.boolean, builder.extract_element(val, ir.Constant(i32, k))
        return ty, val

    def lane_by_lane(fn: Any) -> Any:
        """Lowering that calls the float function ``fn`` once per lane, the same code as the floats."""
        def lower(context: Any, builder: Any, sig: Any, args: Any) -> Any:
            out = ir.Constant(vf64, ir.Undefined)
            for k in range(W):
                pairs = [lane_value(builder, t, v, k) for t, v in zip(sig.args, args)]
                scalar_sig = signature(types.float64, *[p[0] for p in pairs])
                r = context.compile_internal(builder, fn, scalar_sig, [p[1] for p in pairs])
                out = builder.insert_element(out, r, ir.Constant(i32, k))
            return out
        return lower

    def _math_lanes(fn: Any, n_args: int, lower: Any) -> None:
        class MathTemplate(AbstractTemplate):
            def generic(self, args: Any, kws: Any) -> Any:
                if len(args) == n_args and not kws and _lanes_operands(args):
                    return signature(lanes, *([lanes] * n_args))
                return None

        infer_global(fn)(MathTemplate)
        lower_builtin(fn, *([LanesType] * n_args))(lower)

    def is_lanes_call(args: tuple[Any, ...]) -> bool:
        return any(getattr(a, "lanes", False) for a in args)

    def overload_lanes(fn: Any, result: Any, lower: Any) -> None:
        """``fn`` called with any lanes argument returns ``result`` computed by ``lower``."""
        n_args = fn.__code__.co_argcount
        names = ", ".join(f"a{i}" for i in range(n_args))
        scope: dict[str, Any] = {"signature": signature, "result": result, "lower": lower}
        exec(f"def call(typingctx, {names}):\n    return signature(result, {names}), lower\n", scope)  # noqa: S102
        scope["call"] = intrinsic(scope["call"])
        exec(f"def impl({names}):\n    return call({names})\n", scope)  # noqa: S102

        def typer(*args: Any) -> Any:
            return scope["impl"] if is_lanes_call(args) else None

        overload(fn, jit_options={}, strict=False)(typer)

    # the float-only fast paths of the laws (``if is_scalar(x): ... math.sin(x) ...``) are typed
    # with lanes too, though never run (is_scalar is False): math's functions, lane by lane, and a
    # branch on a mask that raises if it ever runs
    for fn, n_args in ((math.sin, 1), (math.cos, 1), (math.tan, 1), (math.exp, 1), (math.log, 1),
                       (math.atan, 1), (math.asin, 1), (math.acos, 1), (math.tanh, 1), (math.atan2, 2),
                       (math.hypot, 2)):
        args_src = ", ".join(f"a{i}" for i in range(n_args))
        scope: dict[str, Any] = {"f": fn}
        exec(f"def scalar({args_src}):\n    return f({args_src})\n", scope)  # noqa: S102
        _math_lanes(fn, n_args, lane_by_lane(scope["scalar"]))

    for fn, name in ((math.sqrt, "sqrt"), (math.fabs, "fabs")):
        _math_lanes(fn, 1, lambda context, builder, sig, args, name=name: vector_intrinsic(builder, name, args[0]))

    class Truth(AbstractTemplate):
        def generic(self, args: Any, kws: Any) -> Any:
            if len(args) == 1 and isinstance(args[0], MaskType):
                return signature(types.boolean, mask)
            return None

    infer_global(bool)(Truth)

    @lower_builtin(bool, MaskType)
    def _truth(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        with cgutils.if_unlikely(builder, cgutils.true_bit):
            context.call_conv.return_user_exc(builder, ValueError, (
                "a branch on a per-vehicle value in a lanes kernel (use where(), or is_scalar() to keep the "
                "branch to floats)",))
        return ir.Constant(i1, 0)

    for fn, impl in float_forms():
        name = fn.__name__
        if name == "is_scalar":
            def typer(x: Any) -> Any:
                return (lambda x: False) if is_lanes_call((x,)) else None
            overload(fn, jit_options={}, strict=False)(typer)
        elif name == "any_of":
            overload_lanes(fn, types.boolean, any_of)
        elif name == "all_of":
            overload_lanes(fn, types.boolean, all_of)
        elif name in vector_forms:
            overload_lanes(fn, lanes, vector_forms[name])
        else:
            overload_lanes(fn, lanes, lane_by_lane(impl))
    for fn in lanewise_functions():
        overload_lanes(fn, lanes, lane_by_lane(fn))

    # --- rows of an array as lanes, and lanes back into one vehicle's numbers ---
    def _pointer(context: Any, builder: Any, aryty: Any, ary: Any, j: Any, i0: Any, elem: Any) -> Any:
        arr = context.make_array(aryty)(context, builder, ary)
        ptr = cgutils.get_item_pointer(context, builder, aryty, arr, [j, i0])
        return builder.bitcast(ptr, elem.as_pointer())

    def _array_2d(a: Any) -> bool:
        return isinstance(a, types.Array) and a.ndim == 2 and a.dtype == types.float64

    @overload(load, strict=False)
    def _load(a: Any, j: Any, i0: Any) -> Any:
        if _array_2d(a):
            return lambda a, j, i0: _load_vec(a, j, i0)
        return None

    @intrinsic
    def _load_vec(typingctx: Any, a: Any, j: Any, i0: Any) -> Any:
        def lower(context: Any, builder: Any, sig: Any, args: Any) -> Any:
            p = _pointer(context, builder, sig.args[0], args[0], args[1], args[2], vf64)
            return builder.load(p, align=8)
        return signature(lanes, a, types.intp, types.intp), lower

    @overload(load_int, strict=False)
    def _load_int(a: Any, j: Any, i0: Any) -> Any:
        if _array_2d(a):
            return lambda a, j, i0: _load_int_vec(a, j, i0)
        return None

    @intrinsic
    def _load_int_vec(typingctx: Any, a: Any, j: Any, i0: Any) -> Any:
        def lower(context: Any, builder: Any, sig: Any, args: Any) -> Any:
            p = _pointer(context, builder, sig.args[0], args[0], args[1], args[2], vf64)
            return builder.fptosi(builder.load(p, align=8), vi64)
        return signature(int_lanes, a, types.intp, types.intp), lower

    @overload(store, strict=False)
    def _store(a: Any, j: Any, i0: Any, x: Any) -> Any:
        if _array_2d(a) and (isinstance(x, LanesType) or _number(x) or isinstance(x, types.Boolean)):
            return lambda a, j, i0, x: _store_vec(a, j, i0, x)
        if _array_2d(a) and isinstance(x, IntLanesType):
            return lambda a, j, i0, x: _store_int_vec(a, j, i0, x)
        return None

    @intrinsic
    def _store_vec(typingctx: Any, a: Any, j: Any, i0: Any, x: Any) -> Any:
        def lower(context: Any, builder: Any, sig: Any, args: Any) -> Any:
            xt = sig.args[3]
            v = args[3]
            if isinstance(xt, types.Boolean):
                v, xt = context.cast(builder, v, xt, types.float64), types.float64
            v = as_lanes(context, builder, xt, v)
            builder.store(v, _pointer(context, builder, sig.args[0], args[0], args[1], args[2], vf64), align=8)
            return context.get_dummy_value()
        return signature(types.none, a, types.intp, types.intp, x), lower

    @intrinsic
    def _store_int_vec(typingctx: Any, a: Any, j: Any, i0: Any, x: Any) -> Any:
        def lower(context: Any, builder: Any, sig: Any, args: Any) -> Any:
            v = builder.sitofp(args[3], vf64)
            builder.store(v, _pointer(context, builder, sig.args[0], args[0], args[1], args[2], vf64), align=8)
            return context.get_dummy_value()
        return signature(types.none, a, types.intp, types.intp, x), lower

    def scalar_type(ty: Any) -> Any:
        if isinstance(ty, LanesType):
            return types.float64
        if isinstance(ty, IntLanesType):
            return types.int64
        if isinstance(ty, MaskType):
            return types.boolean
        if isinstance(ty, types.NamedTuple):
            return types.NamedTuple([scalar_type(t) for t in ty.types], ty.instance_class)
        if isinstance(ty, types.BaseTuple):
            return types.Tuple([scalar_type(t) for t in ty.types])
        return ty

    def extract(context: Any, builder: Any, ty: Any, val: Any, k: Any) -> Any:
        if isinstance(ty, (LanesType, IntLanesType, MaskType)):
            return builder.extract_element(val, k)
        if isinstance(ty, types.BaseTuple):
            items = cgutils.unpack_tuple(builder, val, len(ty))
            return context.make_tuple(builder, scalar_type(ty),
                                      [extract(context, builder, t, v, k) for t, v in zip(ty.types, items)])
        return val

    @overload(lane, strict=False)
    def _lane(x: Any, k: Any) -> Any:
        return lambda x, k: _lane_of(x, k)

    @intrinsic
    def _lane_of(typingctx: Any, x: Any, k: Any) -> Any:
        def lower(context: Any, builder: Any, sig: Any, args: Any) -> Any:
            k32 = builder.trunc(args[1], i32)
            return extract(context, builder, sig.args[0], args[0], k32)
        return signature(scalar_type(x), x, types.intp), lower

