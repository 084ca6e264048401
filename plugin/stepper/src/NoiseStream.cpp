#include "knotmm/stepper/NoiseStream.h"

#include "knotmm/stepper/BinaryIO.h"
#include "knotmm/stepper/Philox.h"

#include <cmath>
#include <istream>
#include <ostream>

using namespace KnotMM;

static inline uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

void NoiseStream::seed(uint64_t value) {
    counter = true;
    counterKey = value;
    draws = 0;
    for (auto& word : s)
        word = 0;
    haveSpare = false;
    spare = 0.0;
}

void NoiseStream::seedSequential(uint64_t value) {
    counter = false;
    counterKey = 0;
    draws = 0;
    for (auto& word : s) {
        value += 0x9e3779b97f4a7c15ULL;
        uint64_t z = value;
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
        word = z ^ (z >> 31);
    }
    haveSpare = false;
    spare = 0.0;
}

void NoiseStream::fill(double* out, int count) {
    if (counter) {
        philox::normals(counterKey, takeDraw(), out, count);
        return;
    }
    for (int i = 0; i < count; i++)
        out[i] = sequentialNormal();
}

uint64_t NoiseStream::next() {
    const uint64_t result = rotl(s[1] * 5, 7) * 9;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double NoiseStream::uniform() { return (next() >> 11) * 0x1.0p-53; }

double NoiseStream::sequentialNormal() {
    if (haveSpare) {
        haveSpare = false;
        return spare;
    }
    double u, v, q;
    do {
        u = 2.0 * uniform() - 1.0;
        v = 2.0 * uniform() - 1.0;
        q = u * u + v * v;
    } while (q >= 1.0 || q == 0.0);
    const double scale = std::sqrt(-2.0 * std::log(q) / q);
    spare = v * scale;
    haveSpare = true;
    return u * scale;
}

void NoiseStream::writeSequential(std::ostream& stream) const {
    stream.write((const char*) s, sizeof(s));
    stream.write((const char*) &haveSpare, sizeof(bool));
    stream.write((const char*) &spare, sizeof(double));
}

void NoiseStream::readSequential(std::istream& stream) {
    stream.read((char*) s, sizeof(s));
    stream.read((char*) &haveSpare, sizeof(bool));
    stream.read((char*) &spare, sizeof(double));
    counter = false;  // layouts 2-5 end here; layout 6 reads its counter state after
}

void NoiseStream::writeCounter(std::ostream& stream) const {
    binary::put(stream, counter);
    binary::put(stream, counterKey);
    binary::put(stream, draws);
}

void NoiseStream::readCounter(std::istream& stream) {
    binary::get(stream, counter);
    binary::get(stream, counterKey);
    binary::get(stream, draws);
}
