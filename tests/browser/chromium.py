"""Debian's headless Chromium under Selenium, as the browser checks start it.

The flags keep Chromium from reaching out on a closed network (background
networking, component updates, sync) and give each run a profile of its
own, removed by `stop`.
"""

import shutil
import tempfile

from selenium import webdriver
from selenium.webdriver.chrome.service import Service


def start(timeout, window="1280,900", log_console=False):
    """A headless Chromium driven by chromium-driver; returns (driver, profile)."""
    profile = tempfile.mkdtemp(prefix="rt-chromium-")
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for a in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
              "--disable-background-networking", "--disable-component-update", "--disable-sync",
              f"--window-size={window}", f"--user-data-dir={profile}"):
        options.add_argument(a)
    if log_console:
        options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    try:
        driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
    except Exception:
        shutil.rmtree(profile, ignore_errors=True)
        raise
    driver.set_page_load_timeout(timeout)
    driver.set_script_timeout(timeout)
    return driver, profile


def stop(driver, profile):
    """Quit `driver` (if any) and remove its profile."""
    if driver is not None:
        try:
            driver.quit()
        except Exception:  # noqa: BLE001 - a driver already gone is gone
            pass
    shutil.rmtree(profile, ignore_errors=True)
