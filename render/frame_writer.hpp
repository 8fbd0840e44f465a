#pragma once
/// \file frame_writer.hpp
/// Writes rendered frames to numbered PNG files on a thread of its own, so encoding never holds
/// up rendering. A fixed pool of image buffers: when every buffer is waiting to be written the
/// renderer gets none and drops that frame (counted) rather than falling behind.
/// The writer keeps nothing per frame: each finished frame goes to an `on_written` callback (on
/// the writer thread), so memory stays constant over a recording of any length.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "render/png_io.hpp"

namespace stroma::render {

/// One frame written to disk.
struct WrittenFrame {
  uint64_t index = 0;       ///< the number in the file name (0, 1, 2, … with no gaps)
  int64_t stamp_ns = 0;     ///< the caller's timestamp (e.g. when the state was published)
  int64_t written_ns = 0;   ///< CLOCK_MONOTONIC when the file was complete
  double sim_time = 0;
  uint64_t state_frame = 0;
  double render_ms = 0;     ///< how long the frame took to render
};

/// Background PNG writer with a bounded pool of buffers.
class FrameWriter {
 public:
  /// Called on the writer thread once per frame when its file is complete, in frame order.
  using WrittenCallback = std::function<void(const WrittenFrame&)>;

  /// Frames go to `dir`/frame_NNNNNN.png at zlib `level`; `buffers` images in flight at most;
  /// `on_written` (may be empty) hears of each frame on disk.
  FrameWriter(std::string dir, int level = 1, int buffers = 6, WrittenCallback on_written = {});
  ~FrameWriter();
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;

  /// A free buffer to render into, or nullptr if all are queued (the caller drops the frame).
  Image* acquire();
  /// Queues `image` (from acquire) as the next frame.
  void submit(Image* image, int64_t stamp_ns, double sim_time, uint64_t state_frame, double render_ms = 0);
  /// Returns an acquired buffer unused.
  void release(Image* image);
  /// Waits until every queued frame is on disk and stops the thread.
  void finish();

  /// How many frames are on disk so far.
  uint64_t written() const;
  uint64_t submitted() const { return next_index_; }
  /// The first write error ("" if none); writing stops at the first error.
  std::string error() const;
  /// Path of frame `index`.
  std::string path(uint64_t index) const;

 private:
  struct Job {
    Image* image;
    WrittenFrame info;
  };
  void run();
  std::string dir_;
  int level_;
  std::vector<Image> pool_;
  std::vector<Image*> free_;
  std::deque<Job> queue_;
  WrittenCallback on_written_;
  uint64_t written_ = 0;
  uint64_t next_index_ = 0;
  bool stopping_ = false;
  std::string error_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::thread thread_;
};

/// CLOCK_MONOTONIC in nanoseconds (the same clock across processes on one host).
int64_t monotonic_ns();

}  // namespace stroma::render
