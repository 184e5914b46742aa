// Reading the CSV files users give (fields, sphere lists) and those ces-sim
// writes (compare): one notion of a field, a number and a readable file,
// so that every reader accepts and refuses the same text.
#pragma once
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace ces::csv {

// The file opened for reading; throws naming the path when it is not a
// regular file (a device or a pipe may never end) or cannot be opened.
std::ifstream open(const std::filesystem::path& path);

// Without the blanks (space, tab, carriage return) around it.
std::string_view trim(std::string_view s);

// The comma-separated fields of a line, each trimmed.
std::vector<std::string_view> split(std::string_view line);

// The line without a leading UTF-8 byte-order mark (spreadsheet exports).
std::string_view without_bom(std::string_view line);

// One finite number making up the whole field (a leading '+' allowed),
// read whatever the locale; nothing otherwise.
std::optional<double> number(std::string_view field);

}  // namespace ces::csv
