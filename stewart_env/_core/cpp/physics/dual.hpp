// A number with N directional derivatives: the kernels' number type for forward-mode automatic
// differentiation (docs/physics.md section 11).
//
// The kernels of kernels.hpp and rk4.hpp are templates over their number type; run on Dual<N>
// they compute the value and its derivatives along N directions at once, by the chain rule applied
// to each operation, from the same source as the values: no equation is written twice.  The value
// part of every operation is the IEEE operation double would do, in the same order, so the values
// come out bit for bit those of the double kernels.  Comparisons, pivot choices and selects act on
// the value part (a branch is taken as the values take it; its derivative is that branch's).
//
// A Dual whose derivatives are all zero (a parameter, a literal) is marked inactive and its
// derivatives are neither stored nor computed: most of a kernel's operations touch a parameter, and
// an operation with one inactive operand costs N multiplications instead of 2N and an addition.
//
// Include this header before kernels.hpp and rk4.hpp: the kernels call lanes::sqrt_of,
// lanes::select, ... by their qualified names, which finds the overloads declared before them.
#pragma once

#include <cmath>
#include <cstdint>

#include "physics/lanes.hpp"

// The operations are small and called in every line of the kernels: inlined always, so that the
// compiler sees through the temporaries (a call copies its arguments).
#if defined(__GNUC__) || defined(__clang__)
#define STEWART_ENV_DUAL_INLINE inline __attribute__((always_inline))
#else
#define STEWART_ENV_DUAL_INLINE inline
#endif

namespace dual {

//: A value v and its derivatives d[0..N) along N directions; d is meaningful only when active.
//: The derivatives first and the whole on a cache line's boundary: the kernels copy Duals by value
//: (V3 and friends), and a copy or an operation on d that straddles no line runs in whole vector
//: moves (the step's Jacobians in half the time of the unaligned layout).
template <int N>
struct alignas(64) Dual {
    double d[N];
    double v;
    bool active;
    Dual() = default;
    Dual(double x) : v(x), active(false) {}  // NOLINT: implicit, so literals and parameters mix with duals
    //: The value x with derivative 1 along direction k (a seed of forward mode).
    static Dual seed(double x, int k) {
        Dual r(x);
        r.active = true;
        for (int j = 0; j < N; ++j) r.d[j] = 0.0;
        r.d[k] = 1.0;
        return r;
    }
    //: Derivative along direction k (0 when inactive).
    double derivative(int k) const { return active ? d[k] : 0.0; }
};

template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator+(const Dual<N>& a, const Dual<N>& b) {
    Dual<N> r(a.v + b.v);
    if (a.active && b.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = a.d[k] + b.d[k];
    } else if (a.active || b.active) {
        r.active = true;
        const double* d = a.active ? a.d : b.d;
        for (int k = 0; k < N; ++k) r.d[k] = d[k];
    }
    return r;
}

template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator-(const Dual<N>& a) {
    Dual<N> r(-a.v);
    if (a.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = -a.d[k];
    }
    return r;
}

template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator-(const Dual<N>& a, const Dual<N>& b) {
    Dual<N> r(a.v - b.v);
    if (a.active && b.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = a.d[k] - b.d[k];
    } else if (a.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = a.d[k];
    } else if (b.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = -b.d[k];
    }
    return r;
}

// (ab)' = a' b + a b'
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator*(const Dual<N>& a, const Dual<N>& b) {
    Dual<N> r(a.v * b.v);
    if (a.active && b.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = a.d[k] * b.v + a.v * b.d[k];
    } else if (a.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = a.d[k] * b.v;
    } else if (b.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = a.v * b.d[k];
    }
    return r;
}

// (a/b)' = (a' - (a/b) b') / b
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator/(const Dual<N>& a, const Dual<N>& b) {
    Dual<N> r(a.v / b.v);
    if (a.active && b.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = (a.d[k] - r.v * b.d[k]) / b.v;
    } else if (a.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = a.d[k] / b.v;
    } else if (b.active) {
        r.active = true;
        for (int k = 0; k < N; ++k) r.d[k] = -(r.v * b.d[k]) / b.v;
    }
    return r;
}

template <int N>
STEWART_ENV_DUAL_INLINE Dual<N>& operator+=(Dual<N>& a, const Dual<N>& b) {
    return a = a + b;
}
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N>& operator-=(Dual<N>& a, const Dual<N>& b) {
    return a = a - b;
}
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N>& operator*=(Dual<N>& a, const Dual<N>& b) {
    return a = a * b;
}
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N>& operator/=(Dual<N>& a, const Dual<N>& b) {
    return a = a / b;
}

// Mixed with a double (a literal): the double is a constant, no Dual made of it.
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator+(double a, const Dual<N>& b) {
    return Dual<N>(a) + b;
}
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator+(const Dual<N>& a, double b) {
    return a + Dual<N>(b);
}
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator-(double a, const Dual<N>& b) {
    return Dual<N>(a) - b;
}
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator-(const Dual<N>& a, double b) {
    return a - Dual<N>(b);
}
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator*(double a, const Dual<N>& b) {
    return Dual<N>(a) * b;
}
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator*(const Dual<N>& a, double b) {
    return a * Dual<N>(b);
}
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator/(double a, const Dual<N>& b) {
    return Dual<N>(a) / b;
}
template <int N>
STEWART_ENV_DUAL_INLINE Dual<N> operator/(const Dual<N>& a, double b) {
    return a / Dual<N>(b);
}

// Comparisons on the value part: the branch the values take.
template <int N>
STEWART_ENV_DUAL_INLINE bool operator>(const Dual<N>& a, const Dual<N>& b) {
    return a.v > b.v;
}
template <int N>
STEWART_ENV_DUAL_INLINE bool operator<(const Dual<N>& a, const Dual<N>& b) {
    return a.v < b.v;
}
template <int N>
STEWART_ENV_DUAL_INLINE bool operator==(const Dual<N>& a, const Dual<N>& b) {
    return a.v == b.v;
}
template <int N>
STEWART_ENV_DUAL_INLINE bool operator!=(const Dual<N>& a, const Dual<N>& b) {
    return a.v != b.v;
}

}  // namespace dual

namespace lanes {

// The Dual faces of the kernels' operations (lanes.hpp has the double and Lanes ones).

// sqrt(a)' = a' / (2 sqrt(a)): infinite at a = 0 (a leg of zero length), which the callers flag.
template <int N>
STEWART_ENV_DUAL_INLINE dual::Dual<N> sqrt_of(const dual::Dual<N>& a) {
    dual::Dual<N> r(std::sqrt(a.v));
    if (a.active) {
        r.active = true;
        const double twice = 2.0 * r.v;
        for (int k = 0; k < N; ++k) r.d[k] = a.d[k] / twice;
    }
    return r;
}
// |a|, its derivative the sign of the value times a' (the pivot's magnitude).
template <int N>
STEWART_ENV_DUAL_INLINE dual::Dual<N> abs_of(const dual::Dual<N>& a) {
    return a.v < 0.0 ? -a : a;
}
template <int N>
STEWART_ENV_DUAL_INLINE dual::Dual<N> select(bool m, const dual::Dual<N>& a, const dual::Dual<N>& b) {
    return m ? a : b;
}
template <int N>
STEWART_ENV_DUAL_INLINE bool finite(const dual::Dual<N>& a) {
    return std::isfinite(a.v);
}
template <int N>
STEWART_ENV_DUAL_INLINE double get(const dual::Dual<N>& x, int) {
    return x.v;
}
template <int N>
STEWART_ENV_DUAL_INLINE void put(dual::Dual<N>& x, int, double value) {
    x = dual::Dual<N>(value);
}

}  // namespace lanes
