// Fixed, locale-independent number formats: equal results give equal bytes.
// Reals are printed like printf("%.9g") (std::to_chars, so LC_NUMERIC cannot
// turn the decimal point into a comma); integers exactly.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>

namespace ces::output {

void append_number(std::string& out, double v);
void append_number(std::string& out, std::uint64_t v);
void append_number(std::string& out, std::int64_t v);
inline void append_number(std::string& out, int v) { append_number(out, std::int64_t(v)); }
std::string format_number(double v);

// SVG coordinates: fixed two decimals, locale-independent.
std::string svg_number(double v);
// Text for XML attributes and elements (&, <, >, ").
std::string xml_escape(const std::string& s);

// Appends CSV rows to a string; fields are separated by commas. Text fields
// are names from the scene (materials, products), written as is.
class CsvWriter {
 public:
  explicit CsvWriter(std::string& out) : text_(&out) {}
  template <class T>
  CsvWriter& operator<<(const T& value) {
    separate();
    if constexpr (std::is_convertible_v<const T&, std::string_view>)
      *text_ += std::string_view(value);
    else
      append_number(*text_, value);
    return *this;
  }
  void end_row() {
    *text_ += '\n';
    row_started_ = false;
  }

 private:
  void separate() {
    if (row_started_) *text_ += ',';
    row_started_ = true;
  }
  std::string* text_;
  bool row_started_ = false;
};

}  // namespace ces::output
