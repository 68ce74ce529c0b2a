/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * compiler.h: the compiler-dependent definitions that sba 1.6 ships beside sba.h and that
 * programs written for it include ("compiler.h", or "../compiler.h" from 1.6's demo). It is
 * installed beside sba.h. The library itself does not use it; it exists so that such programs
 * compile unchanged.
 *
 *   inline         usable as a function specifier in C with every compiler:
 *                  - C++ and C99 or later: the language's own keyword, never redefined;
 *                  - GCC, clang and ICC in C90 modes: their own inline, spelled __inline__
 *                    (strict C90, -std=c89/-ansi, has no inline keyword);
 *                  - MSVC's C compiler before C99 support: __inline;
 *                  - any other C90 compiler: defined as nothing (the functions are then
 *                    ordinary static functions).
 *   SBA_FINITE(x)  nonzero when the double x is neither infinite nor NaN: isfinite where the
 *                  language has it (C99, C++11), _finite with MSVC, the compiler's builtin
 *                  with GCC/clang in C90, and finite (1.6's choice) elsewhere. isfinite rather
 *                  than finite because glibc declares finite only outside strict ISO modes:
 *                  a -std=c99 -pedantic program would otherwise call an undeclared function.
 *                  This header includes <math.h> (and <float.h> for MSVC), so the macro works
 *                  wherever compiler.h is included.
 *
 * The include guard is 1.6's _COMPILER_H_ (a reserved name, kept because programs may test it).
 */
#ifndef _COMPILER_H_
#define _COMPILER_H_

#include <math.h>
#if defined(_MSC_VER)
#include <float.h>
#endif

/* ---- inline: only ever (re)defined when compiling C before C99, where it is no keyword ---- */
#if !defined(__cplusplus) && !defined(inline) && \
    !(defined(__STDC_VERSION__) && __STDC_VERSION__ >= 199901L)
#if defined(__GNUC__) || defined(__INTEL_COMPILER) || defined(__ICC)
/* The compiler's own inline under the spelling it accepts in every C90 mode: strict ISO C90
 * has no inline keyword, and clang -pedantic flags GNU C90's inline as an extension. */
#define inline __inline__
#elif defined(_MSC_VER)
#define inline __inline
#else
#define inline
#endif
#endif

/* ---- SBA_FINITE(x) ---- */
#if defined(_MSC_VER)
#define SBA_FINITE(x) _finite(x)
#elif (defined(__STDC_VERSION__) && __STDC_VERSION__ >= 199901L) || \
    (defined(__cplusplus) && __cplusplus >= 201103L)
#define SBA_FINITE(x) isfinite(x)
#elif defined(__clang__) || \
    (defined(__GNUC__) && (__GNUC__ > 4 || (__GNUC__ == 4 && __GNUC_MINOR__ >= 4)))
#define SBA_FINITE(x) __builtin_isfinite(x)
#else
#define SBA_FINITE(x) finite(x)
#endif

#endif /* _COMPILER_H_ */
