#!/usr/bin/python3
"""The status page in a real browser: headless Chromium driven by Selenium.

Starts `rayfarm broker --serve` with two throttled `rayfarm worker`s, submits a
job with `rayfarm submit`, and checks what a person watching would see: the
job appears, the workers appear in the table, the preview loads and changes as
rows come in, progress reaches 100% and the final image is shown (equal to the
image `rayfarm fetch` writes), a click on the finished job shows its record.
Then it stops the broker under the open page and expects the "broker
unreachable" state. Screenshots go to the output folder. Exit code 0 = every
check passed.
"""
import argparse
import base64
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

from selenium import webdriver
from selenium.common.exceptions import WebDriverException
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

WIDTH, HEIGHT, SPP = 160, 120, 16
WORKERS = {"slow-1": 80, "slow-2": 40}  # name -> throttle: a job of several seconds


def fail(message):
    print("FAIL: " + message, file=sys.stderr)
    sys.exit(1)


def wait_for(driver, what, condition, timeout=60):
    """Polls `condition` until it returns something true. The page redraws its
    tables every second, so an element found a moment ago may be gone: retry."""
    end = time.monotonic() + timeout
    last_error = None
    while time.monotonic() < end:
        try:
            result = condition(driver)
            if result:
                return result
        except WebDriverException as e:
            last_error = e
        time.sleep(0.1)
    detail = f" (last error: {type(last_error).__name__})" if last_error else ""
    fail(f"timed out after {timeout} s waiting for: {what}{detail}")


class Farm:
    """A broker service on free loopback ports and two throttled workers."""

    def __init__(self, rayfarm, tmp):
        self.rayfarm, self.tmp = rayfarm, tmp
        state = os.path.join(tmp, "state")
        self.log = open(os.path.join(tmp, "broker.log"), "w")
        self.broker = subprocess.Popen(
            [rayfarm, "broker", "--serve", "--state", state, "--http", "127.0.0.1:0",
             "--bind", "tcp://127.0.0.1:*", "--announce", "tcp://127.0.0.1:*", "--no-progress"],
            stdout=self.log, stderr=subprocess.STDOUT)
        note = os.path.join(state, "service.json")
        end = time.monotonic() + 30
        while not os.path.exists(note):
            if self.broker.poll() is not None or time.monotonic() > end:
                fail("the broker service did not start: " + open(self.log.name).read())
            time.sleep(0.05)
        time.sleep(0.1)  # written whole by then (a small file, one write)
        where = json.load(open(note))
        self.url = where["http"]
        self.workers = [subprocess.Popen(
            [rayfarm, "worker", "--connect", where["workers"], "--name", name, "--threads", "1",
             "--credit", "1", "--throttle", str(throttle), "--quiet"]) for name, throttle in WORKERS.items()]

    def run(self, *args):
        out = subprocess.run([self.rayfarm, *args, "--broker", self.url], capture_output=True, text=True, timeout=60)
        if out.returncode != 0:
            fail(f"rayfarm {args[0]} failed: {out.stderr}")
        return out.stdout.strip()

    def stop_broker(self):
        self.broker.send_signal(signal.SIGTERM)
        self.broker.wait(timeout=20)

    def close(self):
        for p in (*self.workers, self.broker):
            if p.poll() is None:
                p.kill()
                p.wait()
        self.log.close()


def browser():
    options = Options()
    options.binary_location = "/usr/bin/chromium"
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1000",
                 "--hide-scrollbars", "--force-device-scale-factor=1"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)


# The displayed preview's pixels, read back through a canvas (same origin).
PIXELS_JS = """
const img = document.getElementById('preview');
if (img.hidden || !img.complete || !img.naturalWidth) return null;
const c = document.createElement('canvas');
c.width = img.naturalWidth; c.height = img.naturalHeight;
const g = c.getContext('2d');
g.drawImage(img, 0, 0);
const d = g.getImageData(0, 0, c.width, c.height).data;
const rgb = [];
for (let i = 0; i < d.length; i += 4) rgb.push(d[i], d[i + 1], d[i + 2]);
return [c.width, c.height, rgb];
"""


def shown_pixels(driver):
    got = driver.execute_script(PIXELS_JS)
    if not got:
        return None
    width, height, rgb = got
    return width, height, hashlib.sha256(bytes(rgb)).hexdigest()


def png_pixels_hash(driver, url):
    """Decodes a PNG the broker wrote, in the browser, and hashes its RGB."""
    script = """
const done = arguments[arguments.length - 1];
const img = new Image();
img.onload = () => {
  const c = document.createElement('canvas');
  c.width = img.naturalWidth; c.height = img.naturalHeight;
  const g = c.getContext('2d'); g.drawImage(img, 0, 0);
  const d = g.getImageData(0, 0, c.width, c.height).data, rgb = [];
  for (let i = 0; i < d.length; i += 4) rgb.push(d[i], d[i + 1], d[i + 2]);
  done(rgb);
};
img.onerror = () => done(null);
img.src = arguments[0];
"""
    rgb = driver.execute_async_script(script, url)
    return hashlib.sha256(bytes(rgb)).hexdigest() if rgb is not None else None


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rayfarm", required=True, help="the rayfarm executable")
    parser.add_argument("--source", required=True, help="the source tree (scenes/)")
    parser.add_argument("--out", required=True, help="folder for screenshots and images")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix="rayfarm-status-page-")
    farm = Farm(args.rayfarm, tmp)
    driver = browser()
    try:
        driver.set_script_timeout(20)
        driver.get(farm.url + "/")
        if driver.title != "rayfarm":
            fail(f"page title {driver.title!r}")
        for name in WORKERS:
            wait_for(driver, f"worker {name} in the workers table",
                     lambda d: d.find_elements(By.CSS_SELECTOR, f'#workers tbody tr[data-worker="{name}"]'))
        print("workers appeared: " + ", ".join(WORKERS))

        scene = os.path.join(args.source, "scenes", "balls.nff")
        job_id = farm.run("submit", scene, "--width", str(WIDTH), "--height", str(HEIGHT), "--spp", str(SPP))
        wait_for(driver, f"job {job_id} in the jobs table",
                 lambda d: d.find_elements(By.CSS_SELECTOR, f'#jobs tbody tr[data-job-id="{job_id}"]'))
        print(f"job {job_id} appeared")

        first = wait_for(driver, "the preview image to load", shown_pixels)
        first_rows = int(driver.find_element(By.ID, "preview").get_attribute("data-rows"))
        print(f"preview loaded at {first_rows}/{HEIGHT} rows")
        if first_rows >= HEIGHT:
            fail("the job finished before the page saw it in progress (raise the throttle)")
        second = wait_for(driver, "the preview to change",
                          lambda d: (p := shown_pixels(d)) and p[2] != first[2] and p)
        print(f"preview changed (now {driver.find_element(By.ID, 'preview').get_attribute('data-rows')} rows)")
        if second[:2] != (WIDTH, HEIGHT):
            fail(f"preview is {second[0]}x{second[1]}, expected {WIDTH}x{HEIGHT}")
        driver.save_screenshot(os.path.join(args.out, "status-page-running.png"))

        wait_for(driver, "progress to reach 100%", lambda d: d.find_element(
            By.CSS_SELECTOR, f'#jobs tr[data-job-id="{job_id}"] .pct').text == "100%", timeout=120)
        wait_for(driver, "the job state 'done'", lambda d: d.find_element(
            By.CSS_SELECTOR, f'#jobs tr[data-job-id="{job_id}"]').get_attribute("data-state") == "done")
        wait_for(driver, "the final image", lambda d: d.find_element(By.ID, "preview").get_attribute("data-rows")
                 == str(HEIGHT))
        print("progress 100%, final image shown")
        final_png = os.path.join(args.out, "status-page-job.png")
        farm.run("fetch", job_id, "-o", final_png)
        with open(final_png, "rb") as f:  # decoded by the same browser as the page's image
            fetched = png_pixels_hash(driver, "data:image/png;base64," + base64.b64encode(f.read()).decode())
        if wait_for(driver, "the final image's pixels", shown_pixels)[2] != fetched:
            fail("the image on the page differs from the image `rayfarm fetch` wrote")
        print("final image on the page equals the fetched image")

        # The table is redrawn every second: a row found a moment ago may be
        # gone when clicked, so find and click it again until the record shows.
        def open_record(d):
            d.find_element(By.CSS_SELECTOR, f'#jobs tr[data-job-id="{job_id}"]').click()
            return d.find_element(By.ID, "record").is_displayed()
        wait_for(driver, "the job record", open_record)
        if "tasks" not in driver.find_element(By.ID, "record-summary").text:
            fail("the record summary lacks the task count")
        metrics = driver.execute_script("return fetch('/metrics').then(r => r.text())")
        if f"rayfarm_rows_done_total {HEIGHT}\n" not in metrics or 'rayfarm_jobs{state="done"} 1\n' not in metrics:
            fail("/metrics does not count the job: " + metrics)
        driver.save_screenshot(os.path.join(args.out, "status-page.png"))
        print(f"screenshot: {os.path.join(args.out, 'status-page.png')}")

        # The broker goes away under the open page.
        farm.stop_broker()
        wait_for(driver, "the 'broker unreachable' state", lambda d: d.find_element(
            By.ID, "connection").get_attribute("data-state") == "unreachable", timeout=20)
        banner = driver.find_element(By.ID, "unreachable")
        if not banner.is_displayed() or "Broker unreachable" not in banner.text:
            fail("no visible 'Broker unreachable' banner")
        if not driver.find_elements(By.CSS_SELECTOR, "#jobs tbody tr[data-job-id]"):
            fail("the page dropped what it last saw")
        driver.save_screenshot(os.path.join(args.out, "status-page-unreachable.png"))
        print("broker stopped: the page shows 'broker unreachable'")
    finally:
        driver.quit()
        farm.close()
        shutil.rmtree(tmp, ignore_errors=True)
    print("PASS")


if __name__ == "__main__":
    main()
