/* Scalar maths of the decode's hot path.
 *
 * PoCL (3.0, the CPU driver) links OpenCL's builtins — floor, fmax, clamp, vload4, dot… — as
 * calls that LLVM does not inline into the kernel (seen in the compiled eval_btf.so: 18 calls
 * of floor alone), which costs a call each and keeps the work-item loop from being vectorised.
 * Where the compiler is clang (PoCL, and the clang-based GPU compilers) the hot path therefore
 * uses clang's builtins, which compile to single instructions (roundss, maxss, sqrtss); any
 * other OpenCL compiler gets the standard functions. Same values either way: floor, fmax, fmin,
 * sqrt, fabs, rint and copysign are exact or correctly rounded. */
#ifndef BTF_BUILTINS_H
#define BTF_BUILTINS_H

#ifdef __clang__
#define BTF_FLOOR(x) __builtin_floorf(x)
#define BTF_FMAX(a, b) __builtin_fmaxf((a), (b))
#define BTF_FMIN(a, b) __builtin_fminf((a), (b))
#define BTF_FABS(x) __builtin_fabsf(x)
#define BTF_SQRT(x) __builtin_sqrtf(x)
#define BTF_RINT(x) __builtin_rintf(x)
#define BTF_COPYSIGN(a, b) __builtin_copysignf((a), (b))
/* fmax of two vectors of one type (clang >= 14: one maxps, no call) */
#define BTF_VMAX(a, b) __builtin_elementwise_max((a), (b))
#define BTF_VMIN(a, b) __builtin_elementwise_min((a), (b))
#else
#define BTF_FLOOR(x) floor(x)
#define BTF_FMAX(a, b) fmax((a), (b))
#define BTF_FMIN(a, b) fmin((a), (b))
#define BTF_FABS(x) fabs(x)
#define BTF_SQRT(x) sqrt(x)
#define BTF_RINT(x) rint(x)
#define BTF_COPYSIGN(a, b) copysign((a), (b))
#define BTF_VMAX(a, b) fmax((a), (b))
#define BTF_VMIN(a, b) fmin((a), (b))
#endif

#endif
