// Field-by-field little-endian serialization: never memcpy a struct onto disk or the wire.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>
#include <vector>
#include <voxwall/core/errors.hpp>

namespace voxwall {

static_assert(std::endian::native == std::endian::little,
              "voxwall stores data little-endian and currently needs a little-endian host");

// Appends integers and floats in little-endian order.
class ByteWriter {
 public:
  explicit ByteWriter(std::vector<std::byte>& out) : out_(out) {}
  template <class T>
  void put(T value) {
    static_assert(std::is_arithmetic_v<T>);
    const std::size_t at = out_.size();
    out_.resize(at + sizeof(T));
    std::memcpy(out_.data() + at, &value, sizeof(T));
  }
  void putBytes(std::span<const std::byte> bytes) {
    if (bytes.empty()) return;
    const std::size_t at = out_.size();
    out_.resize(at + bytes.size());
    std::memcpy(out_.data() + at, bytes.data(), bytes.size());
  }
  void padTo(std::size_t alignment) {
    while (out_.size() % alignment) out_.push_back(std::byte{0});
  }
  std::size_t size() const { return out_.size(); }

 private:
  std::vector<std::byte>& out_;
};

// Reads what ByteWriter wrote; every read is bounds-checked and throws FormatError naming
// `file` and `what` (e.g. "section 'params'") when the bytes run out.
class ByteReader {
 public:
  ByteReader(std::span<const std::byte> bytes, std::string file, std::string what)
      : bytes_(bytes), file_(std::move(file)), what_(std::move(what)) {}
  template <class T>
  T get() {
    static_assert(std::is_arithmetic_v<T>);
    need(sizeof(T));
    T value;
    std::memcpy(&value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  std::span<const std::byte> getBytes(std::size_t n) {
    need(n);
    auto s = bytes_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  void skip(std::size_t n) { need(n), pos_ += n; }
  std::size_t position() const { return pos_; }
  std::size_t remaining() const { return bytes_.size() - pos_; }
  [[noreturn]] void fail(const std::string& message) const {
    throw FormatError(file_, what_ + ": " + message);
  }

 private:
  void need(std::size_t n) const {
    if (n > bytes_.size() - pos_)
      fail("truncated: needs " + std::to_string(n) + " more bytes at offset " +
           std::to_string(pos_) + " of " + std::to_string(bytes_.size()));
  }
  std::span<const std::byte> bytes_;
  std::size_t pos_ = 0;
  std::string file_, what_;
};

}  // namespace voxwall
