// The number type of the kernels: one platform (double) or a lane of LANES platforms (Lanes).
//
// The kernels of kernels.hpp and rk4.hpp are templates over their number type T.  With T = double
// they compute one platform; with T = Lanes they compute LANES platforms at once, one per lane of
// a vector register, the batch laid out as structure of arrays.  Every operation of Lanes acts on
// each lane alone with the IEEE operation double would use (+, -, *, /, sqrt, comparisons; no
// fused multiply-add, the build's -ffp-contract=off), and every branch on data is a select, so a
// platform's numbers come out bit for bit the same in a lane as alone, whatever the batch size,
// the lane it falls in or the thread that computes it.
//
// The batch loops (for_rows) hand blocks of LANES rows to the Lanes kernels and the rows left
// over to the double ones, and spread the blocks over the processor's cores (Helpers).
#pragma once

#include <cmath>
#include <cstdint>

#ifndef _WIN32
#include <pthread.h>
#endif
#if defined(__linux__)
#include <sched.h>
#endif

#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <mutex>
#include <new>
#include <system_error>
#include <thread>

namespace lanes {

//: Platforms per lane vector: 8 doubles fill one AVX-512 register (two AVX2 registers, four SSE2
//: registers where the build targets those).
constexpr int LANES = 8;

#if defined(__GNUC__) || defined(__clang__)
typedef double DoubleVec __attribute__((vector_size(LANES * sizeof(double))));
typedef int64_t MaskVec __attribute__((vector_size(LANES * sizeof(int64_t))));
#define STEWART_ENV_VECTOR_EXTENSIONS 1
#endif

#ifdef STEWART_ENV_VECTOR_EXTENSIONS
//: LANES doubles, one platform each; arithmetic lane by lane.
struct Lanes {
    DoubleVec v;
    Lanes() = default;
    Lanes(double x) : v(x - DoubleVec{}) {}  // NOLINT: implicit, so literals mix with lanes (x - 0 is x, -0 too)
    explicit Lanes(DoubleVec x) : v(x) {}
    double operator[](int k) const { return v[k]; }
    void set(int k, double x) { v[k] = x; }
};
//: The result of comparing two Lanes: all bits set in a lane where the comparison holds.
struct Mask {
    MaskVec m;
};
inline Lanes operator+(Lanes a, Lanes b) { return Lanes(a.v + b.v); }
inline Lanes operator-(Lanes a, Lanes b) { return Lanes(a.v - b.v); }
inline Lanes operator*(Lanes a, Lanes b) { return Lanes(a.v * b.v); }
inline Lanes operator/(Lanes a, Lanes b) { return Lanes(a.v / b.v); }
inline Lanes operator-(Lanes a) { return Lanes(-a.v); }
inline Lanes& operator+=(Lanes& a, Lanes b) { return a = a + b; }
inline Lanes& operator-=(Lanes& a, Lanes b) { return a = a - b; }
inline Lanes& operator*=(Lanes& a, Lanes b) { return a = a * b; }
inline Lanes& operator/=(Lanes& a, Lanes b) { return a = a / b; }
inline Mask operator>(Lanes a, Lanes b) { return {a.v > b.v}; }
inline Mask operator==(Lanes a, Lanes b) { return {a.v == b.v}; }
inline Mask operator!=(Lanes a, Lanes b) { return {a.v != b.v}; }
inline Mask operator&&(Mask a, Mask b) { return {a.m & b.m}; }
inline Mask operator||(Mask a, Mask b) { return {a.m | b.m}; }
inline Mask operator!(Mask a) { return {~a.m}; }
inline Lanes sqrt_of(Lanes a) {
    Lanes r;
    for (int k = 0; k < LANES; ++k) r.v[k] = std::sqrt(a.v[k]);
    return r;
}
inline Lanes abs_of(Lanes a) {
    Lanes r;
    for (int k = 0; k < LANES; ++k) r.v[k] = std::fabs(a.v[k]);
    return r;
}
// a where m holds, else b
inline Lanes select(Mask m, Lanes a, Lanes b) { return Lanes(m.m ? a.v : b.v); }
inline bool any(Mask m) {
    for (int k = 0; k < LANES; ++k)
        if (m.m[k]) return true;
    return false;
}
inline bool all(Mask m) {
    for (int k = 0; k < LANES; ++k)
        if (!m.m[k]) return false;
    return true;
}
inline bool lane(Mask m, int k) { return m.m[k] != 0; }
// whether each lane is finite (neither NaN nor infinite)
inline Mask finite(Lanes a) { return {(a.v - a.v) == (a.v - a.v)}; }
#endif

// The double faces of the same operations, so one template serves both number types.
inline double sqrt_of(double a) { return std::sqrt(a); }
inline double abs_of(double a) { return std::fabs(a); }
inline double select(bool m, double a, double b) { return m ? a : b; }
inline bool any(bool m) { return m; }
inline bool all(bool m) { return m; }
inline bool lane(bool m, int) { return m; }
inline bool finite(double a) { return std::isfinite(a); }

//: A double that counts the floating-point operations done on it (+, -, *, / and sqrt; not sign
//: changes, absolute values, comparisons or selects): the flop count of a kernel, run once on it.
struct Counted {
    double v;
    static inline thread_local int64_t flops = 0;
    Counted() = default;
    Counted(double x) : v(x) {}  // NOLINT: implicit, as Lanes
};
inline Counted operator+(Counted a, Counted b) { return ++Counted::flops, Counted(a.v + b.v); }
inline Counted operator-(Counted a, Counted b) { return ++Counted::flops, Counted(a.v - b.v); }
inline Counted operator*(Counted a, Counted b) { return ++Counted::flops, Counted(a.v * b.v); }
inline Counted operator/(Counted a, Counted b) { return ++Counted::flops, Counted(a.v / b.v); }
inline Counted operator-(Counted a) { return Counted(-a.v); }
inline Counted& operator+=(Counted& a, Counted b) { return a = a + b; }
inline Counted& operator-=(Counted& a, Counted b) { return a = a - b; }
inline Counted& operator*=(Counted& a, Counted b) { return a = a * b; }
inline Counted& operator/=(Counted& a, Counted b) { return a = a / b; }
inline bool operator>(Counted a, Counted b) { return a.v > b.v; }
inline bool operator==(Counted a, Counted b) { return a.v == b.v; }
inline bool operator!=(Counted a, Counted b) { return a.v != b.v; }
inline Counted sqrt_of(Counted a) { return ++Counted::flops, Counted(std::sqrt(a.v)); }
inline Counted abs_of(Counted a) { return Counted(std::fabs(a.v)); }
inline Counted select(bool m, Counted a, Counted b) { return m ? a : b; }

//: Number of platforms a number type carries.
template <typename T>
constexpr int width = 1;
#ifdef STEWART_ENV_VECTOR_EXTENSIONS
template <>
constexpr int width<Lanes> = LANES;
#endif

// Lane k of x (x itself for a double).
inline double get(double x, int) { return x; }
inline void put(double& x, int, double value) { x = value; }
#ifdef STEWART_ENV_VECTOR_EXTENSIONS
inline double get(const Lanes& x, int k) { return x[k]; }
inline void put(Lanes& x, int k, double value) { x.set(k, value); }
#endif

// Load size numbers of each of the width<T> rows starting at row b of an array of rows of
// `stride` doubles (rows `stride` apart) into `to` (size numbers of type T); with stride 0 every
// lane gets row b's numbers.
template <typename T>
inline void load(const double* from, int64_t stride, int64_t b, int size, T* to) {
    for (int k = 0; k < width<T>; ++k) {
        const double* row = from + stride * (b + k);
        for (int j = 0; j < size; ++j) put(to[j], k, row[j]);
    }
}

// Store size numbers of type T into the rows b, b + 1, ... of an array of rows of `stride` doubles.
template <typename T>
inline void store(const T* from, int size, double* to, int64_t stride, int64_t b) {
    for (int k = 0; k < width<T>; ++k) {
        double* row = to + stride * (b + k);
        for (int j = 0; j < size; ++j) row[j] = get(from[j], k);
    }
}

//: Rows of work below which a batch runs on the calling thread alone (waking a helper costs more).
constexpr int64_t MIN_PARALLEL_WORK = 512;

//: The most threads a batch may use (the caller and its helpers): more than the cores of any
//: machine the package targets.  set_num_threads refuses more; STEWART_ENV_THREADS is capped here.
constexpr int MAX_THREADS = 256;

//: Helper threads that share the blocks of a batch with the calling thread: by default one per
//: processor core the process may run on beyond the caller's (set_threads, which the Python
//: package calls for set_num_threads and STEWART_ENV_THREADS, sets the total; 1 leaves the caller
//: alone).  The caller works through the blocks itself and only waits for blocks a helper has
//: started, so a helper the operating system does not schedule in time (a busy machine) costs
//: nothing: it finds no block left.  Which thread computes a block never changes its numbers.
//: A helper the operating system refuses to start (a capped address space or process count)
//: is done without: the pool keeps the threads it got.
class Helpers {
public:
    // The process's pool, its threads started on first use (again in a child after fork).
    static Helpers& pool() {
        static std::once_flag registered;
#ifndef _WIN32
        // a child of fork has none of the parent's threads: it starts its own
        std::call_once(registered, [] { pthread_atfork(nullptr, nullptr, [] { instance() = nullptr; }); });
#endif
        std::lock_guard<std::mutex> lock(creation());
        if (instance() == nullptr) {
            Helpers* made = new Helpers();  // never deleted: detached helpers may outlive exit
            made->resize(wanted_threads());
            instance() = made;
        }
        return *instance();
    }

    // The total thread count a pool is made with, or resized to by set_threads: requested(), or
    // by default the processor cores this process may run on, at most MAX_THREADS.
    static int wanted_threads() {
        const int asked = requested().load();
        return asked > 0 ? asked : default_threads();
    }

    // Use `total` threads (1 .. MAX_THREADS; the caller included) from now on: the pool, if it is
    // running, is resized between two batches; otherwise it is made with them when first needed.
    // Returns the threads the pool has (fewer when the operating system refused some).
    static int set_threads(int total) {
        request(total);
        Helpers& helpers = pool();
        std::lock_guard<std::mutex> one_job(helpers.caller_);
        helpers.resize(wanted_threads());
        return helpers.threads();
    }

    // The total thread count (1 .. MAX_THREADS) a pool not yet started is made with; nothing starts.
    static void request(int total) { requested().store(total < 1 ? 1 : (total > MAX_THREADS ? MAX_THREADS : total)); }

    int threads() const { return helpers_.load() + 1; }

    // Call body(u) for u = 0 .. units - 1, on this thread and the helpers.
    template <typename Body>
    void run(int64_t units, Body& body) {
        std::lock_guard<std::mutex> one_job(caller_);
        Job job{&call<Body>, &body, units, {0}};
        {
            std::lock_guard<std::mutex> lock(mutex_);
            job_ = &job;
            ++generation_;
        }
        wake_.notify_all();
        work(job);
        std::unique_lock<std::mutex> lock(mutex_);
        job_ = nullptr;
        idle_.wait(lock, [this] { return active_ == 0; });
    }

private:
    struct Job {
        void (*invoke)(void*, int64_t);
        void* body;
        int64_t units;
        std::atomic<int64_t> next;
    };

    template <typename Body>
    static void call(void* body, int64_t u) {
        (*static_cast<Body*>(body))(u);
    }

    static void work(Job& job) {
        for (int64_t u = job.next.fetch_add(1); u < job.units; u = job.next.fetch_add(1)) job.invoke(job.body, u);
    }

    static Helpers*& instance() {
        static Helpers* pool = nullptr;
        return pool;
    }

    static std::mutex& creation() {
        static std::mutex m;
        return m;
    }

    // The total set by set_threads; 0: none set, the default.
    static std::atomic<int>& requested() {
        static std::atomic<int> total{0};
        return total;
    }

    // The processor cores this process may run on (its affinity mask, where the system has one),
    // at most MAX_THREADS.
    static int default_threads() {
        int cores = static_cast<int>(std::thread::hardware_concurrency());
#if defined(__linux__)
        cpu_set_t set;
        if (sched_getaffinity(0, sizeof(set), &set) == 0 && CPU_COUNT(&set) > 0) cores = CPU_COUNT(&set);
#endif
        return cores < 1 ? 1 : (cores > MAX_THREADS ? MAX_THREADS : cores);
    }

    Helpers() = default;

    // Keep total - 1 helpers: the surplus exit, the missing start.  Called while no batch runs
    // (at creation, or holding caller_).  A helper the system refuses ends the growth: the pool
    // keeps the helpers it has.
    void resize(int total) {
        std::unique_lock<std::mutex> lock(mutex_);
        limit_ = total - 1;
        if (helpers_.load() > limit_) {
            wake_.notify_all();
            exited_.wait(lock, [this] { return helpers_.load() <= limit_; });
        }
        while (helpers_.load() < limit_) {
            const int index = helpers_.load() + 1;
            try {
                std::thread(&Helpers::help, this, index).detach();
            } catch (const std::system_error&) {  // the system's thread or memory limit
                break;
            } catch (const std::bad_alloc&) {
                break;
            }
            helpers_.store(index);
        }
        limit_ = helpers_.load();
    }

    // The loop of helper number `index` (1, 2, ...): a batch's blocks while it runs, exit when the
    // pool shrinks below it.
    void help(int index) {
#if defined(__linux__)
        pthread_setname_np(pthread_self(), "stewart-helper");  // as tools (top -H, /proc) show it
#endif
        std::unique_lock<std::mutex> lock(mutex_);
        uint64_t seen = generation_;
        for (;;) {
            wake_.wait(lock, [&] { return index > limit_ || (job_ != nullptr && generation_ != seen); });
            if (index > limit_) {
                helpers_.store(helpers_.load() - 1);
                exited_.notify_all();
                return;
            }
            seen = generation_;
            Job* job = job_;
            ++active_;
            lock.unlock();
            work(*job);
            lock.lock();
            if (--active_ == 0) idle_.notify_all();
        }
    }

    std::mutex caller_;  // one batch at a time; a resize waits for it
    std::mutex mutex_;
    std::condition_variable wake_;
    std::condition_variable idle_;
    std::condition_variable exited_;
    Job* job_ = nullptr;
    uint64_t generation_ = 0;
    int active_ = 0;
    std::atomic<int> helpers_{0};  // helper threads running (written under mutex_)
    int limit_ = 0;                // helpers wanted: a helper numbered above it exits
};

// Run row_block(b, tag) over the n rows of a batch: tag is a Lanes for each block of LANES rows
// starting at b, a double for each row left over; the blocks are shared with the Helpers when the
// batch holds at least MIN_PARALLEL_WORK rows times `work` (the cost of a row, in forward
// evaluations).
template <typename RowBlock>
inline void for_rows(int64_t n, int64_t work, RowBlock row_block) {
#ifdef STEWART_ENV_VECTOR_EXTENSIONS
    const int64_t blocks = n / LANES;
    const int64_t rows_in_blocks = blocks * LANES;
#else
    const int64_t blocks = 0;
    const int64_t rows_in_blocks = 0;
#endif
    const int64_t units = blocks + (n - rows_in_blocks);
    auto unit = [&](int64_t u) {
#ifdef STEWART_ENV_VECTOR_EXTENSIONS
        if (u < blocks) {
            row_block(u * LANES, Lanes{});
            return;
        }
#endif
        row_block(rows_in_blocks + (u - blocks), 0.0);
    };
    if (units > 1 && n * work >= MIN_PARALLEL_WORK) {
        Helpers& helpers = Helpers::pool();
        if (helpers.threads() > 1) {
            helpers.run(units, unit);
            return;
        }
    }
    for (int64_t u = 0; u < units; ++u) unit(u);
}

// Run row(b) for each of the n rows of a batch on the calling thread and the Helpers, when the
// batch holds at least MIN_PARALLEL_WORK rows times `work` (for kernels of one platform at a time).
template <typename Row>
inline void for_each_row(int64_t n, int64_t work, Row row) {
    if (n > 1 && n * work >= MIN_PARALLEL_WORK) {
        Helpers& helpers = Helpers::pool();
        if (helpers.threads() > 1) {
            helpers.run(n, row);
            return;
        }
    }
    for (int64_t b = 0; b < n; ++b) row(b);
}

}  // namespace lanes
