// Bit patterns of IEEE doubles that the packs' exponent operations use
// (pack_*.h: exponent_field, with_exponent_field, power_of_two).
#pragma once

namespace rayfarm::simd {
namespace {

// 2^52: added to an integer 0 <= k < 2^52, it leaves k in the mantissa bits.
constexpr double kTwo52 = 4503599627370496.0;
constexpr long long kTwo52Bits = 0x4330000000000000ll;
constexpr long long kSignAndMantissa = static_cast<long long>(0x800fffffffffffffull);

}  // namespace
}  // namespace rayfarm::simd
