// The relay's monitor page (GET /monitor) in a real headless Chromium, driven by
// puppeteer-core: a real edgephys-relay process, rooms created and closed over the admin
// API, real SDK clients (admin_test_client) joining and leaving. The page must show every
// room and player the test makes, and follow each change without a reload; its room map must
// list what GET /v1/rooms/{id}/map lists and draw each player's entities in its colour.
//
//   node monitor_test.mjs RELAY_BIN CLIENT_BIN [SCREENSHOT.png]
//
// Prints "SKIPPED: ..." and exits 0 only when Chromium cannot start (ctest skips on that).
// Every wait is bounded; every process it starts is stopped by its pid.
import { spawn } from "node:child_process";
import { mkdtempSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import puppeteer from "puppeteer-core";

const [relayBin, clientBin, screenshot] = process.argv.slice(2);
if (!relayBin || !clientBin) {
  console.error("usage: monitor_test.mjs RELAY_BIN CLIENT_BIN [SCREENSHOT.png]");
  process.exit(2);
}
const chromium = process.env.CHROMIUM || "/usr/bin/chromium";
const KEY = "monitor-test-key-" + Math.random().toString(36).slice(2);
const SECRET = "monitor-test-secret";
const work = mkdtempSync(join(tmpdir(), "edgephys-monitor-"));
const children = [];
const t0 = Date.now();
const step = (what) => console.log(`[${((Date.now() - t0) / 1000).toFixed(1)} s] ${what}`);
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

function start(bin, args, logName) {
  const log = join(work, logName);
  const child = spawn("bash", ["-c", 'exec "$0" "$@" >"' + log + '" 2>&1', bin, ...args],
                      { stdio: "ignore" });
  children.push(child);
  child.log = log;
  return child;
}
const readLog = (child) => { try { return readFileSync(child.log, "utf8"); } catch { return ""; } };

async function until(what, fn, timeoutMs = 10000) {
  const end = Date.now() + timeoutMs;
  for (;;) {
    const v = await fn().catch(() => false);
    if (v) return v;
    if (Date.now() > end) throw new Error("timed out waiting for " + what);
    await sleep(100);
  }
}

let browser;
let relay;
let page;
try {
  relay = start(relayBin, ["--bind", "127.0.0.1:0", "--metrics", "off", "--secret", SECRET,
                           "--admin-addr", "127.0.0.1:0", "--admin-key", KEY,
                           "--physics-threads", "1", "--run-for", "120"], "relay.log");
  const addrs = await until("the relay's addresses", async () => {
    const log = readLog(relay);
    const admin = /admin API on http:\/\/([0-9.:]+)\/v1/.exec(log);
    const udp = /listening on udp ([0-9.:]+)/.exec(log);
    return admin && udp ? { admin: admin[1], udp: udp[1] } : false;
  });
  const base = "http://" + addrs.admin;
  const api = async (method, path, body) => {
    const res = await fetch(base + path, {
      method, headers: { Authorization: "Bearer " + KEY, "Content-Type": "application/json" },
      body: body === undefined ? undefined : JSON.stringify(body) });
    if (!res.ok) throw new Error(method + " " + path + ": HTTP " + res.status + " " + await res.text());
    return res.json();
  };
  const client = (room, player, runFor = 60) =>
    start(clientBin, ["--relay", addrs.udp, "--secret", SECRET, "--room", room,
                      "--player", String(player), "--run-for", String(runFor)], `client-${player}.log`);

  try {
    browser = await puppeteer.launch({
      executablePath: chromium, headless: true, timeout: 30000,
      args: ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run"] });
  } catch (e) {
    console.log("SKIPPED: Chromium cannot start (" + chromium + "): " + String(e.message).split("\n")[0]);
    process.exitCode = 0;
    throw null;  // to the cleanup below
  }
  step("chromium started");
  page = await browser.newPage();
  await page.setViewport({ width: 1366, height: 768 });  // a laptop screen
  const pageErrors = [];
  page.on("pageerror", (e) => pageErrors.push(String(e)));
  const requests = [];
  page.on("request", (r) => requests.push(r.url()));

  // A wrong key: the page asks for one instead of showing data.
  await page.goto(base + "/monitor#key=wrong", { waitUntil: "load", timeout: 15000 });
  await page.waitForSelector("#keyform:not([hidden])", { timeout: 10000 });
  step("wrong key: key form shown");
  // The right key, in the fragment: moved to sessionStorage, gone from the address bar.
  await page.goto(base + "/monitor#key=" + encodeURIComponent(KEY), { waitUntil: "load", timeout: 15000 });
  const stored = await page.evaluate(() => [sessionStorage.getItem("edgephys-admin-key"), location.hash]);
  if (stored[0] !== KEY || stored[1] !== "") throw new Error("key handling: " + JSON.stringify(stored));
  await page.evaluate(() => { window.__noReload = true; window.__noConfirm = true; });
  await page.waitForFunction(() => document.getElementById("state").textContent === "ready", { timeout: 10000 });

  // A real mouse click on `sel`. The poll rebuilds the cards every second: puppeteer finds the
  // button, then scrolls to it, then clicks, and a card replaced in between detaches the node
  // it found; then it looks the button up again (at most 5 tries).
  const press = async (sel) => {
    for (let i = 0; ; ++i) {
      try { return await page.click(sel); } catch (e) {
        if (i >= 4 || !/detached|not clickable|No element/i.test(String(e.message))) throw e;
        await sleep(50);
      }
    }
  };
  const roomShown = (id) => page.waitForSelector(`[data-room="${id}"]`, { timeout: 10000 });
  const roomGone = (id) => page.waitForFunction((id) => !document.querySelector(`[data-room="${id}"]`),
                                                { timeout: 10000 }, id);
  const playerShown = (room, p) => page.waitForSelector(`[data-room="${room}"] tr[data-player="${p}"]`, { timeout: 15000 });
  const playerGone = (room, p) => page.waitForFunction((room, p) =>
      !document.querySelector(`[data-room="${room}"] tr[data-player="${p}"]`), { timeout: 15000 }, room, p);

  // A room created over the API appears.
  await api("POST", "/v1/rooms", { id: "arena", capacity: 8, tick_rate_hz: 30, physics: false });
  await roomShown("arena");
  step("room arena shown");
  // Players join: their rows appear, with their link quality.
  for (const p of [11, 12]) client("arena", p);
  await playerShown("arena", 11);
  await playerShown("arena", 12);
  // A room made by a first join, and a player who leaves by himself after a few seconds.
  client("lobby", 31);
  client("lobby", 32, 6);
  await playerShown("lobby", 31);
  await playerShown("lobby", 32);
  step("players 11, 12, 31, 32 shown");
  // Wait until rates are measured (the relay samples once a second), then the screenshot.
  await page.waitForFunction(() => [...document.querySelectorAll('[data-room="arena"] tr[data-player] td:nth-child(3)')]
      .every((td) => parseFloat(td.textContent) > 0) &&
      document.querySelectorAll('tr[data-player]').length === 4, { timeout: 15000 });
  step("RTT measured");
  // History: the relay-wide charts and each room's sparklines have several polls' points.
  await page.waitForFunction(() => {
    const n = (sel) => Number(document.querySelector(sel)?.getAttribute("data-points") || 0);
    return n('#charts [data-chart="players"]') >= 3 && n('#charts [data-chart="out"]') >= 3 &&
           n('[data-room="arena"] [data-chart="room:arena:players"]') >= 3;
  }, { timeout: 15000 });
  const playersNow = await page.$eval('#charts [data-chart="players"] b', (e) => e.textContent);
  if (playersNow !== "4") throw new Error("players chart shows " + playersNow + ", not 4");
  const line = await page.$eval('#charts [data-chart="players"] polyline', (e) => e.getAttribute("points"));
  if (line.split(" ").length < 3) throw new Error("players chart has no line: " + line);
  step("charts drawn from the page's history");
  // Search and sort.
  await page.type("#search", "lob");
  await page.waitForFunction(() => !document.querySelector('[data-room="arena"]') &&
                             document.querySelector('[data-room="lobby"]'), { timeout: 5000 });
  await page.$eval("#search", (e) => { e.value = ""; e.dispatchEvent(new Event("input")); });
  await page.select("#sort", "id");
  await page.waitForFunction(() => [...document.querySelectorAll("[data-room]")].map((e) => e.dataset.room).join() === "arena,lobby",
                             { timeout: 5000 });
  step("search and sort");
  // The map: arena (first by id) is mapped until another room is chosen; its canvas shows what
  // GET /v1/rooms/arena/map lists, each player's entities in that player's colour.
  await press('[data-room="lobby"] button.map-toggle');
  await page.waitForSelector('[data-room="lobby"] canvas.room-map', { timeout: 5000 });
  if (await page.$('[data-room="arena"] canvas.room-map')) throw new Error("two rooms mapped at once");
  await press('[data-room="arena"] button.map-toggle');
  await page.waitForSelector('[data-room="arena"] canvas.room-map[data-drawn]', { timeout: 5000 });
  const apiMap = await api("GET", "/v1/rooms/arena/map");
  if (apiMap.total !== 2 || apiMap.entities.some((e) => e.owner !== 11 && e.owner !== 12)) {
    throw new Error("arena map from the API: " + JSON.stringify(apiMap));
  }
  const drawn = await page.waitForFunction((n) => {
    const card = document.querySelector('[data-room="arena"]');
    const c = card && card.querySelector("canvas.room-map");
    if (!c || Number(c.dataset.drawn) !== n || Number(c.dataset.listed) !== n) return false;
    // Each player's colour (its legend swatch) must cover a marker's worth of pixels; the
    // grid, background and the room's and PhyS's marks are grey.
    const { data } = c.getContext("2d").getImageData(0, 0, c.width, c.height);
    const perPlayer = {};
    for (const item of card.querySelectorAll("[data-legend-player]")) {
      const rgb = getComputedStyle(item.querySelector("i")).backgroundColor.match(/\d+/g).map(Number);
      let count = 0;
      for (let i = 0; i < data.length; i += 4) {
        if (Math.abs(data[i] - rgb[0]) + Math.abs(data[i + 1] - rgb[1]) + Math.abs(data[i + 2] - rgb[2]) < 24) ++count;
      }
      perPlayer[item.dataset.legendPlayer] = count;
    }
    const counts = Object.values(perPlayer);
    return counts.length === 2 && counts.every((k) => k >= 40) ? perPlayer : false;
  }, { timeout: 10000 }, apiMap.total);
  const mapInfo = await drawn.jsonValue();
  const legend = await page.$$eval('[data-room="arena"] [data-legend-player]', (els) => els.map((e) => e.textContent));
  if (legend.length !== 2 || !/player 11 \(1\)/.test(legend[0]) || !/player 12 \(1\)/.test(legend[1])) {
    throw new Error("map legend: " + JSON.stringify(legend));
  }
  const countText = await page.$eval('[data-room="arena"] .map-count', (e) => e.textContent);
  if (!/2 entities/.test(countText) || !/grid \d+ (m|cm)/.test(countText)) throw new Error("map caption: " + countText);
  step("map drawn: " + JSON.stringify(mapInfo) + "; " + countText);
  await sleep(1500);
  if (screenshot) await page.screenshot({ path: screenshot, fullPage: true });
  const text = await page.$eval('[data-room="arena"]', (e) => e.textContent);
  if (!/2 \/ 8 players/.test(text) || !/physics off/.test(text) || !/30 Hz/.test(text)) {
    throw new Error("arena card: " + text);
  }
  step("screenshot taken");
  // Leaves: player 32 by himself, player 12 kicked.
  await playerGone("lobby", 32);
  // The kick button of player 12's row.
  // Held over a poll: while the mouse button is down the page keeps the card, so the release
  // lands on the button pressed and the click counts.
  const kickAt = await until("the kick button's box", async () =>
    (await page.$('[data-room="arena"] tr[data-player="12"] button.kick'))?.boundingBox(), 5000);
  await page.mouse.move(kickAt.x + kickAt.width / 2, kickAt.y + kickAt.height / 2);
  await page.mouse.down();
  await sleep(1600);
  await page.mouse.up();
  await playerGone("arena", 12);
  await until("player 12 disconnected kicked", async () => /disconnected 4 /.test(readLog(children.find((c) => c.log.endsWith("client-12.log")))));
  await playerShown("arena", 11);
  step("players 32 (left) and 12 (kicked) gone");
  // The close button of room lobby.
  await press('[data-room="lobby"] button.close');
  await roomGone("lobby");
  await roomShown("arena");
  const rooms = await api("GET", "/v1/rooms");
  if (rooms.rooms.some((r) => r.id === "lobby")) throw new Error("lobby still open after close");
  step("room lobby closed by its button");
  // The drain button: the relay drains.
  await press("#drain");
  await page.waitForFunction(() => document.getElementById("state").textContent === "draining", { timeout: 10000 });
  if ((await api("GET", "/v1/rooms")).draining !== true) throw new Error("drain button: relay not draining");
  step("relay draining after the drain button");
  const stillSamePage = await page.evaluate(() => window.__noReload === true);
  if (!stillSamePage) throw new Error("the page reloaded");
  if (pageErrors.length) throw new Error("page errors: " + pageErrors.join("; "));
  const foreign = requests.filter((u) => !u.startsWith(base));
  if (foreign.length) throw new Error("the page fetched outside the relay: " + foreign.join(", "));
  console.log("monitor test passed (" + requests.length + " requests, all to the relay)" +
              (screenshot ? "; screenshot " + screenshot : ""));
} catch (e) {
  if (e !== null) {
    console.error("FAIL:", e && e.message ? e.message : e);
    if (page) console.error("--- page: " + await page.evaluate(() =>
      document.getElementById("state").textContent + " | " + document.getElementById("error").textContent + " | " + document.getElementById("charts").outerHTML.slice(0, 300)).catch((x) => String(x)));
    if (relay) console.error("--- relay log\n" + readLog(relay).split("\n").slice(-30).join("\n"));
    process.exitCode = 1;
  }
} finally {
  step("cleanup");
  if (browser) await browser.close().catch(() => {});
  for (const c of children) { try { c.kill("SIGTERM"); } catch {} }
  rmSync(work, { recursive: true, force: true });
  step("done");
}
