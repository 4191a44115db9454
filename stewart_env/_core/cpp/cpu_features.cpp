// Which instruction-set targets of the kernels this processor runs (stewart_env._core._cpu_features).
//
// Compiled for the architecture's baseline, so any processor of it imports this module;
// stewart_env/_core/__init__.py asks it before it imports a module of the kernels.  On x86-64 it
// reads the processor's features with CPUID and, for the AVX and AVX-512 registers, asks the
// operating system (XGETBV) whether it saves them: a processor with AVX-512 under a system that
// does not save the registers cannot run x86-64-v4 code.  The targets' feature lists are those of
// the x86-64 psABI's micro-architecture levels, which GCC's and Clang's -march=x86-64-v3 and
// -march=x86-64-v4 compile for.
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cstdint>
#include <string>
#include <vector>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <cpuid.h>
#define STEWART_ENV_CPUID 1
#endif

namespace nb = nanobind;

namespace {

//: Every target, from the least to the most demanding.
const char* const TARGETS[] = {"baseline", "x86-64-v3", "x86-64-v4"};

#ifdef STEWART_ENV_CPUID
enum Register { EBX, ECX };

//: A processor feature: the CPUID leaf (sub-leaf 0) and the register and bit that report it.
struct Feature {
    const char* name;
    unsigned leaf;
    Register reg;
    int bit;
};

//: x86-64-v2, which x86-64-v3 includes.
const Feature V2[] = {{"cx16", 1, ECX, 13},  {"lahf_lm", 0x80000001u, ECX, 0}, {"popcnt", 1, ECX, 23},
                      {"sse3", 1, ECX, 0},   {"sse4_1", 1, ECX, 19},           {"sse4_2", 1, ECX, 20},
                      {"ssse3", 1, ECX, 9}};
const Feature V3[] = {{"avx", 1, ECX, 28},  {"avx2", 7, EBX, 5},  {"bmi1", 7, EBX, 3},
                      {"bmi2", 7, EBX, 8},  {"f16c", 1, ECX, 29}, {"fma", 1, ECX, 12},
                      {"lzcnt", 0x80000001u, ECX, 5}, {"movbe", 1, ECX, 22}, {"xsave", 1, ECX, 26}};
const Feature V4[] = {{"avx512f", 7, EBX, 16}, {"avx512bw", 7, EBX, 30}, {"avx512cd", 7, EBX, 28},
                      {"avx512dq", 7, EBX, 17}, {"avx512vl", 7, EBX, 31}};

bool has(const Feature& f) {
    unsigned a = 0, b = 0, c = 0, d = 0;
    if (!__get_cpuid_count(f.leaf, 0, &a, &b, &c, &d)) return false;  // a leaf the processor lacks
    return (((f.reg == EBX ? b : c) >> f.bit) & 1u) != 0;
}

template <size_t N>
bool has_all(const Feature (&features)[N]) {
    for (const Feature& f : features)
        if (!has(f)) return false;
    return true;
}

//: The register states the operating system saves on a context switch (XCR0), 0 where it says
//: nothing (no OSXSAVE).
uint64_t saved_states() {
    if (!has({"osxsave", 1, ECX, 27})) return 0;
    unsigned lo = 0, hi = 0;
    __asm__ volatile("xgetbv" : "=a"(lo), "=d"(hi) : "c"(0));
    return (static_cast<uint64_t>(hi) << 32) | lo;
}

constexpr uint64_t AVX_STATES = 0x6;       // XMM and the upper halves of YMM
constexpr uint64_t AVX512_STATES = 0xe0;   // the opmask registers, the upper halves of ZMM0-15, ZMM16-31
#endif

//: The targets this processor and its operating system run, from the least to the most demanding.
std::vector<std::string> runnable() {
    std::vector<std::string> out = {TARGETS[0]};
#ifdef STEWART_ENV_CPUID
    const uint64_t states = saved_states();
    const bool v3 = has_all(V2) && has_all(V3) && (states & AVX_STATES) == AVX_STATES;
    if (v3) out.push_back(TARGETS[1]);
    if (v3 && has_all(V4) && (states & AVX512_STATES) == AVX512_STATES) out.push_back(TARGETS[2]);
#endif
    return out;
}

}  // namespace

NB_MODULE(_cpu_features, m) {
    m.doc() = "The instruction-set targets of the compiled kernels that this processor runs.";
    m.attr("TARGETS") = nb::make_tuple(TARGETS[0], TARGETS[1], TARGETS[2]);
    m.def("runnable", &runnable,
          "The targets this processor and its operating system run, from the least to the most demanding.");
}
