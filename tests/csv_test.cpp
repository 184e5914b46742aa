// The CSV reading every data file shares (fields, sphere lists, compare):
// one notion of a field and a number, whoever reads.
#include "common/csv.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "feed/shapes.hpp"
#include "support.hpp"

namespace ces::csv {
namespace {

TEST(Csv, FieldsAreSplitAtCommasAndTrimmed) {
  const auto fields = split(" x ,\ty,,z\r");
  ASSERT_EQ(fields.size(), 4u);
  EXPECT_EQ(fields[0], "x");
  EXPECT_EQ(fields[1], "y");
  EXPECT_EQ(fields[2], "");
  EXPECT_EQ(fields[3], "z");
  EXPECT_EQ(trim(" \t\r "), "");
  EXPECT_EQ(without_bom("\xEF\xBB\xBFx,y"), "x,y");
  EXPECT_EQ(without_bom("x,y"), "x,y");
}

TEST(Csv, ANumberIsTheWholeFieldAndFinite) {
  EXPECT_EQ(number("1.5"), 1.5);
  EXPECT_EQ(number("+1.5"), 1.5);
  EXPECT_EQ(number("-2e-3"), -2e-3);
  EXPECT_EQ(number("+.5"), 0.5);
  for (const char* bad : {"", "+", "++1", "1.5x", "1,5", "nan", "inf", "+inf", "-inf", "+-1",
                          "1e999", "1e-400", "0x1p3", " 1"})
    EXPECT_FALSE(number(bad).has_value()) << "'" << bad << "'";
}

// A sphere list from a spreadsheet: a byte-order mark before its header,
// a '+' sign; a device is refused before it is read.
TEST(Csv, SphereListsReadWhatTheFieldReaderReads) {
  const auto path = test::fresh_dir("csv") / "spheres.csv";
  std::ofstream(path) << "\xEF\xBB\xBFx, y, z, r\r\n0,0,0,+0.5\r\n# a comment\n1,0,0,0.5\n";
  const feed::SphereList list = feed::read_sphere_csv(path);
  ASSERT_EQ(list.radii.size(), 2u);
  EXPECT_EQ(list.radii[0], 0.5);
  EXPECT_EQ(list.centers[1].x(), 1.0);
  EXPECT_THROW(feed::read_sphere_csv("/dev/zero"), std::runtime_error);
  EXPECT_THROW(open("/dev/zero"), std::runtime_error);
}

}  // namespace
}  // namespace ces::csv
