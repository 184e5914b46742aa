// The scene format as a Markdown reference, made from the schema: every
// key, its type or quantity, its default, its range and its description.
// docs/scene-format.md is this text (`ces-sim schema --markdown`), and a
// test keeps the two the same.
#pragma once
#include <string>

namespace ces::scene {

std::string schema_markdown();

}  // namespace ces::scene
