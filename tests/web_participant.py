"""A scripted participant in headless Chromium (Selenium + Debian's chromium-driver), and a study server.

:class:`StudyServer` serves an exported study folder on 127.0.0.1 (optionally slowly, to test
image preloading; POSTs are stored as the study's data endpoint). :func:`browser` starts Chromium
with a download folder; :func:`answer_until` plays the participant: it reads which screen is up
from the page and answers it by keyboard or mouse as a person would.
"""

from __future__ import annotations

import http.server
import threading
import time
from collections.abc import Callable
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import Any


class _Handler(http.server.SimpleHTTPRequestHandler):
    delay_s = 0.0
    posted: list[tuple[str, bytes]]
    served: list[tuple[float, str]]

    def log_message(self, *args: Any) -> None:  # quiet
        pass

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        if self.delay_s and self.path.split("?")[0].startswith("/img/"):
            time.sleep(self.delay_s)
        super().do_GET()
        self.served.append((time.monotonic(), self.path))

    def do_POST(self) -> None:  # noqa: N802
        n = int(self.headers.get("Content-Length", 0))
        self.posted.append((self.headers.get("X-Appeal-File", ""), self.rfile.read(n)))
        self.send_response(200)
        self.end_headers()
        self.wfile.write(b"ok")


class StudyServer:
    """A static server of ``folder`` on 127.0.0.1 in a thread; ``delay_s`` slows every image."""

    def __init__(self, folder: Path, delay_s: float = 0.0):
        handler = type("H", (_Handler,), {"delay_s": delay_s, "posted": [], "served": []})
        self.handler = handler
        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), partial(handler, directory=str(folder)))
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.httpd.server_address[1]}/"

    @property
    def posted(self) -> list[tuple[str, bytes]]:
        return self.handler.posted

    def __enter__(self) -> StudyServer:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


@contextmanager
def browser(downloads: Path, size: tuple[int, int] = (1280, 1024)):
    """Headless Chromium driven by chromedriver, saving downloads into ``downloads``."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    downloads.mkdir(parents=True, exist_ok=True)
    opts = webdriver.ChromeOptions()
    opts.binary_location = "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              f"--window-size={size[0]},{size[1]}", "--autoplay-policy=no-user-gesture-required"):
        opts.add_argument(a)
    opts.add_experimental_option("prefs", {"download.default_directory": str(downloads),
                                           "download.prompt_for_download": False})
    driver = webdriver.Chrome(options=opts, service=Service("/usr/bin/chromedriver"))
    try:
        driver.set_window_size(*size)
        driver.execute_cdp_cmd("Browser.setDownloadBehavior", {"behavior": "allow", "downloadPath": str(downloads)})
        yield driver
    finally:
        driver.quit()


def state(driver: Any) -> str:
    """The study's state (``running``, ``complete``, ``error`` or ``''`` while loading)."""
    return driver.execute_script("return document.body ? (document.body.dataset.appealState || '') : ''")


def answer_until(driver: Any, stop: Callable[[Any], bool], *, choose: Callable[[str, Any], Any] | None = None,
                 timeout_s: float = 240.0, shots: dict[str, Path] | None = None) -> dict[str, int]:
    """Answer every screen until ``stop(driver)``; returns how many screens of each kind were answered.

    Likert scales are answered by number key (every third by a mouse click), classifications by
    the choice's key (or a click when it has none); instruction, break and resume pages by SPACE,
    the full-screen page by its button. ``choose(kind, elements)`` may pick the answer.
    ``shots`` maps screen kinds to PNG paths: the first screen of each kind is saved there.
    """
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    counts: dict[str, int] = {}
    end = time.monotonic() + timeout_s
    last: Any = None

    def press(key: str) -> None:
        ActionChains(driver).send_keys(key).perform()

    def shot(kind: str) -> None:
        if shots is not None and kind in shots and not shots[kind].exists():
            driver.save_screenshot(str(shots[kind]))

    while not stop(driver):
        if time.monotonic() > end:
            raise TimeoutError(f"the study did not finish in {timeout_s} s (answered {counts})")
        if state(driver) == "error":
            raise RuntimeError(driver.find_element(By.CSS_SELECTOR, ".appeal-error").text)
        found = driver.find_elements(By.CSS_SELECTOR, ".appeal-tick, .appeal-choice, .appeal-page, .appeal-text, "
                                                      "#jspsych-fullscreen-btn")
        if not found or found[0] == last:
            time.sleep(0.02)
            continue
        el = found[0]
        last = el
        cls = f"{el.get_attribute('class')} {el.get_attribute('id')}"
        if "appeal-tick" in cls:
            kind = "likert"
            shot(kind)
            ticks = found
            pick = choose(kind, ticks) if choose else ticks[(counts.get(kind, 0) * 3) % len(ticks)]
            if counts.get(kind, 0) % 3 == 2:
                pick.click()
            else:
                press(pick.text)
        elif "appeal-choice" in cls:
            kind = "classification"
            shot(kind)
            pick = choose(kind, found) if choose else found[counts.get(kind, 0) % len(found)]
            text = pick.text
            if text.startswith("["):
                press(text[1:text.index("]")])
            else:
                pick.click()
        elif "fullscreen" in cls:
            kind = "fullscreen"
            el.click()
        else:
            kind = "page"
            shot(kind)
            press(" ")
        counts[kind] = counts.get(kind, 0) + 1
    return counts


def wait_for_file(folder: Path, pattern: str, timeout_s: float = 20.0) -> Path:
    """The downloaded file matching ``pattern`` once Chromium has finished writing it."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        done = [p for p in folder.glob(pattern) if not p.name.endswith(".crdownload")]
        if done:
            return done[0]
        time.sleep(0.1)
    raise TimeoutError(f"no download matching {pattern} in {folder}")
