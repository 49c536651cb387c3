#pragma once
// The one little-endian byte codec of the project's binary formats (accumulator checkpoints,
// coordinator checkpoints, the merge journal). Every value is written least significant byte
// first on every host, so a file written on one machine reads back on any other; floating
// point values travel as their IEEE-754 bit patterns. Reading is bounds-checked: a short input
// throws InputError("<what>: truncated") instead of reading past the end (docs/design.md, E2).

#include <bit>
#include <concepts>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>

#include "common/core/error.h"

namespace pf {

template <typename T>
concept CodecValue = std::is_arithmetic_v<T> && !std::same_as<T, bool> && (sizeof(T) <= 8);

// The unsigned integer with T's bits.
template <CodecValue T>
using CodecBits = std::conditional_t<
    sizeof(T) == 1, uint8_t,
    std::conditional_t<sizeof(T) == 2, uint16_t, std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>>;

// Writes `v` as sizeof(T) little-endian bytes at `out`.
template <CodecValue T>
inline void StoreLittleEndian(char* out, T v) {
  const auto bits = std::bit_cast<CodecBits<T>>(v);
  for (size_t i = 0; i < sizeof(T); ++i) out[i] = char((uint64_t(bits) >> (8 * i)) & 0xff);
}

// Reads sizeof(T) little-endian bytes at `in` (the caller checked the length).
template <CodecValue T>
inline T LoadLittleEndian(const char* in) {
  uint64_t bits = 0;
  for (size_t i = 0; i < sizeof(T); ++i) bits |= uint64_t(static_cast<unsigned char>(in[i])) << (8 * i);
  return std::bit_cast<T>(CodecBits<T>(bits));
}

// Appends values to a byte string.
class ByteWriter {
 public:
  explicit ByteWriter(std::string& out) : out_(out) {}

  template <CodecValue T>
  void Put(T v) {
    char buf[sizeof(T)];
    StoreLittleEndian(buf, v);
    out_.append(buf, sizeof(T));
  }
  // An array of values. On little-endian hosts the bytes are the array's own, copied at once
  // (a 16-Mpx accumulator is ~0.5 GB: no per-element loop there).
  template <CodecValue T>
  void PutArray(std::span<const T> values) {
    if constexpr (std::endian::native == std::endian::little) {
      out_.append(reinterpret_cast<const char*>(values.data()), values.size_bytes());
    } else {
      for (T v : values) Put(v);
    }
  }
  void PutBytes(std::string_view bytes) { out_.append(bytes); }

 private:
  std::string& out_;
};

// Consumes values from the front of a byte view.
class ByteReader {
 public:
  // `what` names the format in error messages ("checkpoint", "journal entry", ...).
  ByteReader(std::string_view in, std::string what) : in_(in), what_(std::move(what)) {}

  template <CodecValue T>
  T Get() {
    Need(sizeof(T));
    const T v = LoadLittleEndian<T>(in_.data());
    in_.remove_prefix(sizeof(T));
    return v;
  }
  template <CodecValue T>
  void GetArray(std::span<T> out) {
    Need(out.size_bytes());
    if constexpr (std::endian::native == std::endian::little) {
      if (!out.empty()) std::memcpy(out.data(), in_.data(), out.size_bytes());
      in_.remove_prefix(out.size_bytes());
    } else {
      for (T& v : out) v = Get<T>();
    }
  }
  std::string_view GetBytes(uint64_t n) {
    Need(n);
    const std::string_view bytes = in_.substr(0, size_t(n));
    in_.remove_prefix(size_t(n));
    return bytes;
  }

  size_t remaining() const { return in_.size(); }
  bool empty() const { return in_.empty(); }
  std::string_view rest() const { return in_; }
  [[noreturn]] void Fail(const std::string& reason) const { throw InputError(what_ + ": " + reason); }

 private:
  void Need(uint64_t n) const {
    if (in_.size() < n) Fail("truncated");
  }
  std::string_view in_;
  std::string what_;
};

}  // namespace pf
