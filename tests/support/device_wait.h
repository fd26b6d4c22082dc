#pragma once
// Test doubles for work on a "device" (DeviceWait, slam/dynamic/segmenter.h): a wait that blocks
// as a scheduler's resumption does, and a device that is a thread of its own.
#include <functional>
#include <future>
#include <thread>

#include "slam/dynamic/segmenter.h"

namespace pcr::test {

// A DeviceWait that blocks until done(): counts its calls and remembers the thread that called
// done().
struct BlockingWait {
  int waits = 0, dones = 0;
  std::thread::id done_thread;
  DeviceWait Get() {
    return [this](const std::function<void(const DeviceDone&)>& launch) {
      ++waits;
      std::promise<void> finished;
      std::future<void> ended = finished.get_future();
      launch([this, &finished] {
        ++dones;
        done_thread = std::this_thread::get_id();
        finished.set_value();
      });
      ended.wait();
    };
  }
};

// Runs `work` on a thread of its own, the device, launched through `wait`, and calls done()
// after it; returns when the wait does (the device thread joined).
inline void RunOnDeviceThread(const DeviceWait& wait, const std::function<void()>& work) {
  std::promise<DeviceDone> launched;
  std::thread device([&work, started = launched.get_future()]() mutable {
    const DeviceDone done = started.get();
    work();
    done();
  });
  wait([&launched](const DeviceDone& done) { launched.set_value(done); });
  device.join();
}

}  // namespace pcr::test
