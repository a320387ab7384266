/* Included first by every C file of the native FMUs: no contraction of a * b + c into a fused
 * multiply-add, whatever flags a tool compiles the sources with, so that every platform
 * computes the floats of the pythonfmu FMUs (each product and sum rounded on its own). */
#ifndef DRONEFLY_EXACT_H
#define DRONEFLY_EXACT_H
#if defined(__clang__)
#pragma clang fp contract(off)
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#elif defined(_MSC_VER)
#pragma fp_contract(off)
#endif
#endif
