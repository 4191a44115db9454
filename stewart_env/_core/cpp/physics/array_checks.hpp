// The shape check of the arrays the Python bindings take, shared by every binding source: no call
// from Python reads or writes outside an array.
#pragma once

#include <nanobind/nanobind.h>

#include <cstdint>
#include <initializer_list>
#include <string>

namespace array_checks {

// Raise ValueError naming the array unless its shape is `shape` (-1: any size).
template <typename A>
inline void expect(const A& a, const char* name, std::initializer_list<int64_t> shape) {
    bool ok = a.ndim() == shape.size();
    size_t d = 0;
    for (int64_t s : shape) {
        if (!ok) break;
        ok = s < 0 || static_cast<int64_t>(a.shape(d)) == s;
        ++d;
    }
    if (!ok) {
        std::string got = "(";
        for (size_t k = 0; k < a.ndim(); ++k) got += (k ? ", " : "") + std::to_string(a.shape(k));
        got += ")";
        std::string want = "(";
        d = 0;
        for (int64_t s : shape) want += (d++ ? ", " : "") + (s < 0 ? std::string("N") : std::to_string(s));
        want += ")";
        throw nanobind::value_error((std::string(name) + ": expected shape " + want + ", got " + got).c_str());
    }
}

}  // namespace array_checks
