// Bytes in and out, for checkpoints: the state written as it is in memory
// (same machine kind, same build), read back with every length checked, so
// a damaged file is an error, never a crash or a garbled run.
#pragma once
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "common/math.hpp"

namespace ces {

// Values copied as their bytes: trivially copyable types, and types that
// say so (PlainBytes): the fixed-size Eigen types and plain records of
// them hold their numbers and nothing else, though their copy constructors
// are user-declared.
template <class T>
struct PlainBytes : std::bool_constant<std::is_trivially_copyable_v<T>> {};
template <> struct PlainBytes<Vec2> : std::true_type {};
template <> struct PlainBytes<Vec3> : std::true_type {};
template <> struct PlainBytes<Quat> : std::true_type {};
template <> struct PlainBytes<Mat3> : std::true_type {};
template <> struct PlainBytes<Pose> : std::true_type {};
template <class T>
inline constexpr bool kBytes = PlainBytes<T>::value;

class ByteWriter {
 public:
  template <class T>
  void value(const T& v) {
    static_assert(kBytes<T>);
    bytes_.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  template <class T>
  void values(const std::vector<T>& v) {
    value(std::uint64_t(v.size()));
    if (!v.empty()) bytes_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  void text(std::string_view s) {
    value(std::uint64_t(s.size()));
    bytes_.append(s);
  }
  const std::string& bytes() const { return bytes_; }
  // Room for n bytes in all, so that a writer of a known size never copies
  // what it holds to grow.
  void reserve(std::size_t n) { bytes_.reserve(n); }
  std::string take() && { return std::move(bytes_); }

 private:
  std::string bytes_;
};

// Thrown for a checkpoint that ends early or holds impossible lengths.
class CorruptData : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ByteReader {
 public:
  explicit ByteReader(std::string_view bytes) : bytes_(bytes) {}
  template <class T>
  void value(T& v) {
    static_assert(kBytes<T>);
    std::memcpy(static_cast<void*>(&v), take(sizeof(T)), sizeof(T));
  }
  template <class T>
  T value() {
    T v{};
    value(v);
    return v;
  }
  template <class T>
  void values(std::vector<T>& v) {
    const auto n = value<std::uint64_t>();
    if (n > (bytes_.size() - at_) / sizeof(T)) throw CorruptData("a list longer than the data");
    v.resize(std::size_t(n));
    if (n > 0) std::memcpy(static_cast<void*>(v.data()), take(v.size() * sizeof(T)), v.size() * sizeof(T));
  }
  std::string text() {
    const auto n = value<std::uint64_t>();
    if (n > bytes_.size() - at_) throw CorruptData("a text longer than the data");
    return std::string(take(std::size_t(n)), std::size_t(n));
  }
  bool at_end() const { return at_ == bytes_.size(); }
  std::size_t position() const { return at_; }  // bytes read so far

 private:
  const char* take(std::size_t n) {
    if (n > bytes_.size() - at_) throw CorruptData("the data ends early");
    const char* p = bytes_.data() + at_;
    at_ += n;
    return p;
  }
  std::string_view bytes_;
  std::size_t at_ = 0;
};

}  // namespace ces
