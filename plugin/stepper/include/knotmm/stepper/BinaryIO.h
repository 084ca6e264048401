#ifndef KNOTMM_STEPPER_BINARY_IO_H_
#define KNOTMM_STEPPER_BINARY_IO_H_

// Raw little helpers of the checkpoint layout (native byte order, as OpenMM's own checkpoints).

#include <istream>
#include <ostream>
#include <vector>

namespace KnotMM {
namespace binary {

template <class T>
void put(std::ostream& stream, const T& value) {
    stream.write((const char*) &value, sizeof(T));
}

template <class T>
void get(std::istream& stream, T& value) {
    stream.read((char*) &value, sizeof(T));
}

/** A length (long long) and the numbers. */
inline void putVector(std::ostream& stream, const std::vector<double>& v) {
    long long size = v.size();
    put(stream, size);
    if (size > 0)
        stream.write((const char*) v.data(), sizeof(double) * size);
}

inline void getVector(std::istream& stream, std::vector<double>& v) {
    long long size = 0;
    get(stream, size);
    if (!stream || size < 0 || size > (1LL << 34))
        size = 0;
    v.resize(size);
    if (size > 0)
        stream.read((char*) v.data(), sizeof(double) * size);
}

} // namespace binary
} // namespace KnotMM

#endif
