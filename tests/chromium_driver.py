"""Headless Chromium driven by Selenium for the dashboard's tests in a browser.

Every connection is made to 127.0.0.1, never to "localhost", which a machine without /etc/hosts
(a fresh debootstrap root) cannot resolve: chromedriver is started here and reached by address
(Selenium's own Service says "localhost"), and Chromium is started here too with its DevTools on
127.0.0.1, chromedriver attaching to it by that address (launched by chromedriver, it would be
reached as "localhost" as well).
"""
import os
import socket
import subprocess
import time

from selenium import webdriver


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_port(port, process, what, log_path, seconds):
    deadline = time.monotonic() + seconds
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
            return
        except OSError:
            if process.poll() is not None or time.monotonic() > deadline:
                process.kill()
                raise RuntimeError(f"{what} did not listen on 127.0.0.1:{port} within {seconds} s "
                                   f"(its output: {log_path})")
            time.sleep(0.05)


def start(chromium, chromedriver, args, work_dir, capabilities=(), seconds=20):
    """(driver, processes): a WebDriver session on a headless Chromium started with `args` (its
    profile and the two programs' output in work_dir); the caller quits the driver, then stops the
    processes."""
    browser_log = os.path.join(work_dir, "chromium.log")
    devtools = _free_port()
    browser = subprocess.Popen([chromium, *args, f"--remote-debugging-port={devtools}",
                                "--remote-debugging-address=127.0.0.1",
                                f"--user-data-dir={os.path.join(work_dir, 'chromium-profile')}", "about:blank"],
                               stdout=open(browser_log, "w"), stderr=subprocess.STDOUT)
    processes = [browser]
    try:
        _wait_port(devtools, browser, "Chromium's DevTools", browser_log, seconds)
        driver_log = os.path.join(work_dir, "chromedriver.log")
        port = _free_port()
        server = subprocess.Popen([chromedriver, f"--port={port}", "--allowed-ips=127.0.0.1"],
                                  stdout=open(driver_log, "w"), stderr=subprocess.STDOUT)
        processes.append(server)
        _wait_port(port, server, "chromedriver", driver_log, seconds)
        options = webdriver.ChromeOptions()
        options.debugger_address = f"127.0.0.1:{devtools}"
        for name, value in capabilities:
            options.set_capability(name, value)
        return webdriver.Remote(command_executor=f"http://127.0.0.1:{port}", options=options), processes
    except Exception:
        for p in processes:
            p.kill()
        raise
