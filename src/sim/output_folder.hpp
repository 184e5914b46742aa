// Where a run writes, so that no run loses another's results.
//
// A run writes into DIR/partial while it runs. When it completes, its files
// move into DIR one by one (summary.json last, so "complete" is on disk only
// once everything else is), and the files an earlier run listed in DIR's
// summary.json that this run did not write again are removed: nothing else
// in DIR is touched (a user's own files stay). A run that stops early (a
// signal, an error, a full disk, a kill) leaves DIR as it was, with an
// earlier complete run intact, and its own files in DIR/partial, where
// summary.json says why it stopped and `ces-sim resume DIR` finds its
// checkpoint. One run at a time writes in DIR: another one's start is
// refused while it holds the folder (it would clear DIR/partial under it).
#pragma once
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "common/path.hpp"
#include "output/files.hpp"

namespace ces {

class OutputFolder {
 public:
  // Fresh: removes what an earlier unfinished run left in DIR/partial.
  // Resume: keeps it, to continue. Throws output::IoError while another
  // run holds DIR.
  OutputFolder(std::filesystem::path dir, output::Start start);
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  const std::filesystem::path& dir() const { return dir_; }
  // Where the run writes while it runs.
  const std::filesystem::path& work() const { return work_; }

  // Moves `files` (paths relative to work(); summary.json among them) into
  // dir(), removes the earlier run's files not among them, and removes
  // work().
  void publish(const std::vector<std::string>& files) const;

 private:
  std::filesystem::path dir_, work_;
  std::unique_ptr<FolderLock> lock_;  // DIR's, while the run lives
};

}  // namespace ces
