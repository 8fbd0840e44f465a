#include "render/frame_writer.hpp"

#include <time.h>

#include <algorithm>

#include <fmt/format.h>

namespace stroma::render {

int64_t monotonic_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

FrameWriter::FrameWriter(std::string dir, int level, int buffers, WrittenCallback on_written)
    : dir_(std::move(dir)),
      level_(level),
      pool_(static_cast<size_t>(std::max(1, buffers))),
      on_written_(std::move(on_written)) {
  for (Image& i : pool_) free_.push_back(&i);
  thread_ = std::thread([this] { run(); });
}

FrameWriter::~FrameWriter() { finish(); }

std::string FrameWriter::path(uint64_t index) const { return fmt::format("{}/frame_{:06d}.png", dir_, index); }

Image* FrameWriter::acquire() {
  std::lock_guard lock(mutex_);
  if (free_.empty() || !error_.empty()) return nullptr;
  Image* i = free_.back();
  free_.pop_back();
  return i;
}

void FrameWriter::release(Image* image) {
  std::lock_guard lock(mutex_);
  free_.push_back(image);
}

void FrameWriter::submit(Image* image, int64_t stamp_ns, double sim_time, uint64_t state_frame, double render_ms) {
  {
    std::lock_guard lock(mutex_);
    WrittenFrame info;
    info.index = next_index_++;
    info.stamp_ns = stamp_ns;
    info.sim_time = sim_time;
    info.state_frame = state_frame;
    info.render_ms = render_ms;
    queue_.push_back({image, info});
  }
  cv_.notify_one();
}

void FrameWriter::finish() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
}

uint64_t FrameWriter::written() const {
  std::lock_guard lock(mutex_);
  return written_;
}

std::string FrameWriter::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

void FrameWriter::run() {
  for (;;) {
    Job job;
    bool failed = false;
    {
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, and everything is written
      job = queue_.front();
      queue_.pop_front();
      failed = !error_.empty();
    }
    std::string err;
    const bool ok = !failed && write_png(path(job.info.index), *job.image, level_, &err);
    if (ok) job.info.written_ns = monotonic_ns();
    {
      std::lock_guard lock(mutex_);
      free_.push_back(job.image);
      if (ok) {
        ++written_;
      } else if (error_.empty()) {
        error_ = err;
      }
    }
    // Outside the lock: the callback may do I/O (a frames.csv row) while the renderer acquires.
    if (ok && on_written_) on_written_(job.info);
  }
}

}  // namespace stroma::render
