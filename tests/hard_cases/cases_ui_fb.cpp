// ui_fb: corrupt button scripts, floods of bouncing edges and extreme times
// through the debouncer, framebuffer packing with bad strides and formats,
// screens drawn from hostile view models, non-finite images blitted.
#include <cstdlib>
#include <limits>
#include <random>

#include "catalogue.h"
#include "propcam/ui_fb/buttons.h"
#include "propcam/ui_fb/canvas.h"
#include "propcam/ui_fb/pixel_format.h"
#include "propcam/ui_fb/screens.h"

namespace propcam::hard_cases {
namespace {

using namespace propcam::ui_fb;

void add_events(Digest& d, const std::vector<ButtonEvent>& events) {
  d.integer(static_cast<std::int64_t>(events.size()));
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
  for (const ButtonEvent& e : events) {
    check(e.time_ns >= last, "events are in time order");
    last = e.time_ns;
    d.integer(static_cast<int>(e.button));
    d.integer(static_cast<int>(e.kind));
    d.integer(e.time_ns);
  }
}

Canvas gradient_canvas(int w, int h) {
  Canvas c(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      c.set_pixel(x, y, {static_cast<std::uint8_t>(x * 31), static_cast<std::uint8_t>(y * 17), 200});
  return c;
}

}  // namespace

void add_ui_fb_cases(std::vector<HardCase>& cases) {
  const std::string m = "ui_fb";
  cases.push_back({"ScriptOfBinaryGarbage", m, "a button script of control bytes and 0xff around \"press OK\"",
                   "error naming <script>:1", Expect::Error, {"<script>:1"}, [](Digest&) {
                     ButtonScript::parse(std::string("\x01\x02press OK\xff\xfe\n", 13));
                   }});
  cases.push_back({"ScriptWithNegativeTime", m, "a button script line \"at -1s press OK\"",
                   "error naming <script>:1", Expect::Error, {"<script>:1"}, [](Digest&) {
                     ButtonScript::parse("at -1s press OK\n");
                   }});
  cases.push_back({"ScriptPressingAButtonThatIsDown", m, "a button script \"down OK\" twice",
                   "error naming line 2", Expect::Error, {"<script>:2"}, [](Digest&) {
                     ButtonScript::parse("down OK\ndown OK\n");
                   }});
  cases.push_back({"DebouncerFloodOfEdges", m,
                   "20000 random edges on all five buttons within 50 ms (seeded), then 10 s of quiet",
                   "a finite, time-ordered event list, every button released", Expect::Result, {},
                   [](Digest& d) {
                     ButtonDebouncer deb;
                     std::mt19937 rng(7);
                     std::array<bool, kButtonCount> level{};
                     for (int i = 0; i < 20000; ++i) {
                       const std::size_t b = rng() % kButtonCount;
                       level[b] = !level[b];
                       deb.on_edge({kAllButtons[b], level[b], static_cast<std::int64_t>(i) * 2500});
                     }
                     for (std::size_t b = 0; b < kButtonCount; ++b)
                       if (level[b]) deb.on_edge({kAllButtons[b], false, 50'000'000});
                     deb.advance(10'050'000'000);
                     for (Button b : kAllButtons) check(!deb.is_held(b), "every button is released");
                     add_events(d, deb.take_events());
                   }});
  cases.push_back({"DebouncerAtTheEndOfTime", m, "OK pressed at INT64_MAX - 1 ms and time advanced to INT64_MAX",
                   "finite, ordered events; times clamped, no overflow", Expect::Result, {}, [](Digest& d) {
                     ButtonDebouncer deb;
                     const std::int64_t end = std::numeric_limits<std::int64_t>::max();
                     deb.on_edge({Button::Ok, true, end - 1'000'000});
                     deb.advance(end);
                     deb.on_edge({Button::Ok, false, end});
                     deb.advance(end);
                     add_events(d, deb.take_events());
                     d.integer(static_cast<std::int64_t>(deb.clamped_times()));
                   }});
  cases.push_back({"PackWithTooShortStride", m, "pack an 8x4 canvas as XRGB8888 with a 16-byte line stride (32 needed)",
                   "error naming the line stride", Expect::Error, {"stride"}, [](Digest&) {
                     const Canvas c = gradient_canvas(8, 4);
                     std::vector<std::uint8_t> frame(16 * 4);
                     pack_pixels(c, c.bounds(), FramebufferFormat::xrgb8888(), frame, 16);
                   }});
  cases.push_back({"OverlappingColourFields", m, "a 32-bit framebuffer format whose green field overlaps red",
                   "error naming the overlap", Expect::Error, {"overlapping"}, [](Digest&) {
                     FramebufferFormat f{32, {0, 8}, {4, 8}, {16, 8}, {}};
                     PixelPacker packer(f);
                   }});
  cases.push_back({"Rgb565PaddedStride", m, "pack and unpack a 7x3 canvas as RGB565 with a 20-byte (padded) stride",
                   "finite bytes; the round trip keeps each channel to 5/6/5 bits", Expect::Result, {}, [](Digest& d) {
                     const Canvas c = gradient_canvas(7, 3);
                     std::vector<std::uint8_t> frame(20 * 3, 0xAB);
                     const PixelPacker packer(FramebufferFormat::rgb565());
                     packer.pack(c, c.bounds(), frame, 20);
                     Canvas back(7, 3);
                     packer.unpack(frame, 20, back);
                     for (int y = 0; y < 3; ++y)
                       for (int x = 0; x < 7; ++x) {
                         const Rgb a = c.pixel(x, y), b = back.pixel(x, y);
                         check(std::abs(a.r - b.r) <= 8 && std::abs(a.g - b.g) <= 4 && std::abs(a.b - b.b) <= 8,
                               "RGB565 keeps each channel to its 5 or 6 bits");
                       }
                     for (std::uint8_t byte : frame) d.integer(byte);
                   }});
  cases.push_back({"ScreenFromAHostileView", m,
                   "draw_screen (Rendering) on 96x64: NaN times and errors, an out-of-range selection, a 10000-character title, tiles outside the image, an empty image",
                   "a canvas of finite pixels, no exception", Expect::Result, {}, [](Digest& d) {
                     const double nan = std::numeric_limits<double>::quiet_NaN();
                     ScreenView v;
                     v.kind = ScreenKind::Rendering;
                     v.title = std::string(10000, 'W');
                     v.status = "\xff\xfe not utf-8";
                     v.elapsed_seconds = nan;
                     v.predicted_seconds_to_good = std::numeric_limits<double>::infinity();
                     v.predicted_seconds_to_done = nan;
                     v.converged_fraction = nan;
                     v.selected_tier = 99;
                     v.tiles = {{cv::Rect(-50, -50, 400, 400), true, false, nan, 3},
                                {cv::Rect(1 << 30, 5, 10, 10), true, true, -1.0, -4}};
                     Canvas canvas(96, 64);
                     draw_screen(canvas, v);
                     d.mat(canvas.pixels());
                   }});
  cases.push_back({"BlitNonFiniteLinearImage", m, "blit_scaled a 4x4 linear image holding NaN, +Inf and -1 onto 16x16",
                   "finite 8-bit pixels", Expect::Result, {}, [](Digest& d) {
                     cv::Mat img(4, 4, CV_32FC3, cv::Scalar::all(0.25));
                     img.at<cv::Vec3f>(0, 0) = {std::numeric_limits<float>::quiet_NaN(), 0, 0};
                     img.at<cv::Vec3f>(1, 1) = cv::Vec3f::all(std::numeric_limits<float>::infinity());
                     img.at<cv::Vec3f>(2, 2) = cv::Vec3f::all(-1.f);
                     Canvas canvas(16, 16);
                     const Rect drawn = canvas.blit_scaled(img, {0, 0, 16, 16}, true);
                     d.integer(drawn.width);
                     d.integer(drawn.height);
                     d.mat(canvas.pixels());
                   }});
}

}  // namespace propcam::hard_cases
