// Opens a mapmesh report (report.html) in headless Chromium (Debian's, driven by npm
// playwright-core), waits for every image, and takes a full-page screenshot. Prints one JSON
// object:
//   {"title", "images": n, "broken": [src of an image that did not load or has no size],
//    "too_wide": [src of an image wider than the page shows it], "tables": [ids], "height": px,
//    "page_width": px (wider than view_width: the page scrolls sideways),
//    "sideways": [id or tag of an element that scrolls sideways inside the page],
//    "tallest_image": px (the largest natural height of an image),
//    "shot_clipped": true when the page was taller than a screenshot holds (shot to 16384 px),
//    "console_errors": [...]}
// Usage: node tests/js/report_shot.mjs REPORT.html SHOT.(png|jpg) [WIDTH]
// Exit status 1 with the reason on stderr when the browser cannot open the page.
import { chromium } from "playwright-core";
import { pathToFileURL } from "node:url";

const [page_path, shot, width_arg] = process.argv.slice(2);
if (!page_path || !shot) {
  console.error("usage: node report_shot.mjs REPORT.html SHOT.(png|jpg) [WIDTH]");
  process.exit(2);
}
const width = Number(width_arg ?? 1400);
const MAX_SHOT_PX = 16384;
const executablePath = process.env.CHROMIUM ?? "/usr/bin/chromium";
// Flags for a closed network and a root user in a container (no sandbox, no background calls).
const args = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
              "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage"];
let browser;
try {
  browser = await chromium.launch({ executablePath, args, headless: true, timeout: 60000 });
  const page = await browser.newPage({ viewport: { width, height: 900 } });
  const console_errors = [];
  page.on("console", (m) => { if (m.type() === "error") console_errors.push(m.text()); });
  page.on("pageerror", (e) => console_errors.push(String(e)));
  await page.goto(pathToFileURL(page_path).href, { waitUntil: "load", timeout: 60000 });
  const facts = await page.evaluate(() => {
    const images = [...document.images];
    return {
      title: document.title,
      images: images.length,
      broken: images.filter((i) => !i.complete || i.naturalWidth === 0).map((i) => i.getAttribute("src")),
      too_wide: images.filter((i) => i.getBoundingClientRect().right > document.documentElement.clientWidth + 1)
        .map((i) => i.getAttribute("src")),
      tables: [...document.querySelectorAll("table")].map((t) => t.id),
      height: document.documentElement.scrollHeight,
      page_width: document.documentElement.scrollWidth,
      view_width: document.documentElement.clientWidth,
      sideways: [...document.querySelectorAll("body *")]
        .filter((e) => e.scrollWidth > e.clientWidth + 1 && ["auto", "scroll"].includes(getComputedStyle(e).overflowX))
        .map((e) => e.id || e.firstElementChild?.id || e.tagName.toLowerCase()),
      tallest_image: Math.max(0, ...images.map((i) => i.naturalHeight)),
    };
  });
  const type = shot.endsWith(".jpg") || shot.endsWith(".jpeg") ? "jpeg" : "png";
  // An image format holds at most 16384 px a side in Chromium's encoder: a taller page is shot
  // down to that ("shot_clipped").
  const clip = facts.height > MAX_SHOT_PX ? { x: 0, y: 0, width, height: MAX_SHOT_PX } : undefined;
  await page.screenshot({ path: shot, fullPage: !clip, clip, type, ...(type === "jpeg" ? { quality: 70 } : {}) });
  facts.shot_clipped = Boolean(clip);
  console.log(JSON.stringify({ ...facts, console_errors }));
} catch (e) {
  console.error(`report_shot: ${page_path}: ${e.message.split("\n")[0]}`);
  process.exitCode = 1;
} finally {
  if (browser) await browser.close();
}
