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
// In lanes the two halves of the directions are active apart (Dual::BLOCKS): the caller orders
// its directions so that many numbers depend on one half alone (the derivatives put the pose's
// six first and the twist's six after, and a leg's frame, length and inertias depend on the pose
// alone), and an operation costs nothing in a half neither operand carries.
//
// Include this header before kernels.hpp and rk4.hpp: the kernels call lanes::sqrt_of,
// lanes::select, ... by their qualified names, which finds the overloads declared before them.
#pragma once

#include <cmath>
#include <cstdint>
#include <type_traits>

#include "physics/lanes.hpp"

// The operations are small and called in every line of the kernels: inlined always, so that the
// compiler sees through the temporaries (a call copies its arguments).
#if defined(__GNUC__) || defined(__clang__)
#define STEWART_ENV_DUAL_INLINE inline __attribute__((always_inline))
#else
#define STEWART_ENV_DUAL_INLINE inline
#endif
// The loops over the blocks unrolled, so that each block's offset is a constant (whole aligned
// vector moves) and its activity tests are plain branches.
#if defined(__clang__)
#define STEWART_ENV_EACH_BLOCK _Pragma("unroll")
#elif defined(__GNUC__)
#define STEWART_ENV_EACH_BLOCK _Pragma("GCC unroll 2")
#else
#define STEWART_ENV_EACH_BLOCK
#endif

namespace dual {

//: A value v and its derivatives d[0..N) along N directions, in BLOCKS blocks of N / BLOCKS whose
//: activity is kept apart: the derivatives of block b are meaningful only when active[b].
//: V is double (one platform) or lanes::Lanes (one platform per lane, lanes.hpp): every operation
//: then acts on each lane alone with the operations double does, so a platform's value is bit for
//: bit its own alone, and its derivatives too up to the sign of a zero (an inactive block's
//: derivatives are +0 where one platform's may be a computed -0; the callers add +0 to what they
//: return, which makes them the same bits).  Activity is the same in every lane: it follows the
//: kernel's code path (which numbers depend on a seed), not the data.
//: One platform keeps one block (its twelve derivatives are one and a half vector moves, and
//: testing two blocks at every operation costs it more than the blocks save); in lanes, where
//: each direction is a whole vector, two (the first half and the second).
//: The derivatives first and the whole on a cache line's boundary: the kernels copy Duals by value
//: (V3 and friends), and a copy or an operation on d that straddles no line runs in whole vector
//: moves (the step's Jacobians in half the time of the unaligned layout).
template <int N, typename V = double>
struct alignas(64) Dual {
    //: Blocks of directions active apart.
    static constexpr int BLOCKS = std::is_same_v<V, double> ? 1 : 2;
    static_assert(N % BLOCKS == 0, "the directions split into BLOCKS blocks of equal size");
    //: Directions per block.
    static constexpr int STRIDE = N / BLOCKS;
    V d[N];
    V v;
    bool active[BLOCKS];
    Dual() = default;
    // A copy carries the derivatives of its active blocks only: most numbers a kernel copies are
    // parameters (inactive), whose derivatives would be dead bytes (in lanes, most of a kilobyte).
    Dual(const Dual& o) : v(o.v) { copy_derivatives(o); }
    Dual& operator=(const Dual& o) {
        v = o.v;
        copy_derivatives(o);
        return *this;
    }
    Dual(const V& x) : v(x), active{} {}  // NOLINT: implicit, so literals and parameters mix with duals
    //: A literal in lanes: the same in every lane.
    template <typename U = V, typename = std::enable_if_t<!std::is_same_v<U, double>>>
    Dual(double x) : v(x), active{} {}  // NOLINT: implicit, as above
    //: The value x with derivative 1 along direction k (a seed of forward mode): k's block active.
    static Dual seed(const V& x, int k) {
        Dual r(x);
        r.activate(k / STRIDE);
        r.at(k) = V(1.0);
        return r;
    }
    //: Block b made active with zero derivatives (before a caller sets some).
    void activate(int b) {
        active[b] = true;
        for (int j = b * STRIDE; j < (b + 1) * STRIDE; ++j) d[j] = V(0.0);
    }
    //: The derivative along direction k, as stored (its block must be active).
    V& at(int k) { return d[k]; }
    //: Derivative along direction k (0 when its block is inactive).
    V derivative(int k) const { return active[k / STRIDE] ? d[k] : V(0.0); }

   private:
    void copy_derivatives(const Dual& o) {
        for (int b = 0; b < BLOCKS; ++b) {
            active[b] = o.active[b];
            if (active[b])
                for (int k = b * STRIDE; k < (b + 1) * STRIDE; ++k) d[k] = o.d[k];
        }
    }
};

// Each operation below is the chain rule on each block of directions: an operand inactive in a
// block contributes nothing there, and a block neither operand carries stays inactive.

template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator+(const Dual<N, V>& a, const Dual<N, V>& b) {
    constexpr int S = Dual<N, V>::STRIDE;
    Dual<N, V> r(a.v + b.v);
    STEWART_ENV_EACH_BLOCK
    for (int blk = 0; blk < Dual<N, V>::BLOCKS; ++blk) {
        const int lo = blk * S;
        if (a.active[blk] && b.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = a.d[k] + b.d[k];
        } else if (a.active[blk] || b.active[blk]) {
            r.active[blk] = true;
            const V* d = a.active[blk] ? a.d : b.d;
            for (int k = lo; k < lo + S; ++k) r.d[k] = d[k];
        }
    }
    return r;
}

template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator-(const Dual<N, V>& a) {
    constexpr int S = Dual<N, V>::STRIDE;
    Dual<N, V> r(-a.v);
    STEWART_ENV_EACH_BLOCK
    for (int blk = 0; blk < Dual<N, V>::BLOCKS; ++blk) {
        const int lo = blk * S;
        if (a.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = -a.d[k];
        }
    }
    return r;
}

template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator-(const Dual<N, V>& a, const Dual<N, V>& b) {
    constexpr int S = Dual<N, V>::STRIDE;
    Dual<N, V> r(a.v - b.v);
    STEWART_ENV_EACH_BLOCK
    for (int blk = 0; blk < Dual<N, V>::BLOCKS; ++blk) {
        const int lo = blk * S;
        if (a.active[blk] && b.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = a.d[k] - b.d[k];
        } else if (a.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = a.d[k];
        } else if (b.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = -b.d[k];
        }
    }
    return r;
}

// (ab)' = a' b + a b'
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator*(const Dual<N, V>& a, const Dual<N, V>& b) {
    constexpr int S = Dual<N, V>::STRIDE;
    Dual<N, V> r(a.v * b.v);
    STEWART_ENV_EACH_BLOCK
    for (int blk = 0; blk < Dual<N, V>::BLOCKS; ++blk) {
        const int lo = blk * S;
        if (a.active[blk] && b.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = a.d[k] * b.v + a.v * b.d[k];
        } else if (a.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = a.d[k] * b.v;
        } else if (b.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = a.v * b.d[k];
        }
    }
    return r;
}

// (a/b)' = (a' - (a/b) b') / b
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator/(const Dual<N, V>& a, const Dual<N, V>& b) {
    constexpr int S = Dual<N, V>::STRIDE;
    Dual<N, V> r(a.v / b.v);
    STEWART_ENV_EACH_BLOCK
    for (int blk = 0; blk < Dual<N, V>::BLOCKS; ++blk) {
        const int lo = blk * S;
        if (a.active[blk] && b.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = (a.d[k] - r.v * b.d[k]) / b.v;
        } else if (a.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = a.d[k] / b.v;
        } else if (b.active[blk]) {
            r.active[blk] = true;
            for (int k = lo; k < lo + S; ++k) r.d[k] = -(r.v * b.d[k]) / b.v;
        }
    }
    return r;
}

template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V>& operator+=(Dual<N, V>& a, const Dual<N, V>& b) {
    return a = a + b;
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V>& operator-=(Dual<N, V>& a, const Dual<N, V>& b) {
    return a = a - b;
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V>& operator*=(Dual<N, V>& a, const Dual<N, V>& b) {
    return a = a * b;
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V>& operator/=(Dual<N, V>& a, const Dual<N, V>& b) {
    return a = a / b;
}

// Mixed with a double (a literal): the double is a constant, no Dual made of it.
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator+(double a, const Dual<N, V>& b) {
    return Dual<N, V>(a) + b;
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator+(const Dual<N, V>& a, double b) {
    return a + Dual<N, V>(b);
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator-(double a, const Dual<N, V>& b) {
    return Dual<N, V>(a) - b;
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator-(const Dual<N, V>& a, double b) {
    return a - Dual<N, V>(b);
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator*(double a, const Dual<N, V>& b) {
    return Dual<N, V>(a) * b;
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator*(const Dual<N, V>& a, double b) {
    return a * Dual<N, V>(b);
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator/(double a, const Dual<N, V>& b) {
    return Dual<N, V>(a) / b;
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE Dual<N, V> operator/(const Dual<N, V>& a, double b) {
    return a / Dual<N, V>(b);
}

// Comparisons on the value part: the branch the values take.
template <int N, typename V>
STEWART_ENV_DUAL_INLINE auto operator>(const Dual<N, V>& a, const Dual<N, V>& b) {
    return a.v > b.v;
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE auto operator<(const Dual<N, V>& a, const Dual<N, V>& b) {
    return b.v > a.v;  // as >: Lanes compare with > alone
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE auto operator==(const Dual<N, V>& a, const Dual<N, V>& b) {
    return a.v == b.v;
}
template <int N, typename V>
STEWART_ENV_DUAL_INLINE auto operator!=(const Dual<N, V>& a, const Dual<N, V>& b) {
    return a.v != b.v;
}

}  // namespace dual

namespace lanes {

// The Dual faces of the kernels' operations (lanes.hpp has the double and Lanes ones).

// sqrt(a)' = a' / (2 sqrt(a)): infinite at a = 0 (a leg of zero length), which the callers flag.
template <int N, typename V>
STEWART_ENV_DUAL_INLINE dual::Dual<N, V> sqrt_of(const dual::Dual<N, V>& a) {
    constexpr int S = dual::Dual<N, V>::STRIDE;
    dual::Dual<N, V> r(lanes::sqrt_of(a.v));
    const V twice = 2.0 * r.v;
    STEWART_ENV_EACH_BLOCK
    for (int blk = 0; blk < dual::Dual<N, V>::BLOCKS; ++blk) {
        if (!a.active[blk]) continue;
        r.active[blk] = true;
        for (int k = blk * S; k < (blk + 1) * S; ++k) r.d[k] = a.d[k] / twice;
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
template <int N, typename V>
STEWART_ENV_DUAL_INLINE auto finite(const dual::Dual<N, V>& a) {
    return lanes::finite(a.v);
}
template <int N>
STEWART_ENV_DUAL_INLINE double get(const dual::Dual<N>& x, int) {
    return x.v;
}
template <int N>
STEWART_ENV_DUAL_INLINE void put(dual::Dual<N>& x, int, double value) {
    x = dual::Dual<N>(value);
}

#ifdef STEWART_ENV_VECTOR_EXTENSIONS
// a where m holds, else b, lane by lane, derivatives too; an inactive side's derivatives are zero
// in the lanes that take it (where one platform alone would have taken an inactive number).
template <int N>
STEWART_ENV_DUAL_INLINE dual::Dual<N, Lanes> select(Mask m, const dual::Dual<N, Lanes>& a,
                                                     const dual::Dual<N, Lanes>& b) {
    constexpr int S = dual::Dual<N, Lanes>::STRIDE;
    dual::Dual<N, Lanes> r(select(m, a.v, b.v));
    const Lanes zero(0.0);
    STEWART_ENV_EACH_BLOCK
    for (int blk = 0; blk < dual::Dual<N, Lanes>::BLOCKS; ++blk) {
        if (!a.active[blk] && !b.active[blk]) continue;
        r.active[blk] = true;
        for (int k = blk * S; k < (blk + 1) * S; ++k)
            r.d[k] = select(m, a.active[blk] ? a.d[k] : zero, b.active[blk] ? b.d[k] : zero);
    }
    return r;
}
template <int N>
STEWART_ENV_DUAL_INLINE dual::Dual<N, Lanes> abs_of(const dual::Dual<N, Lanes>& a) {
    return select(Lanes(0.0) > a.v, -a, a);
}
#endif

}  // namespace lanes
