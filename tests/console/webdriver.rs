//! A headless Chromium driven through chromedriver (W3C WebDriver) with fantoccini: open a
//! page, find and click elements, run a script, take a screenshot. The tests are
//! synchronous; a session owns the runtime its client runs on.

use fantoccini::elements::Element;
use fantoccini::{Client, ClientBuilder, Locator};
use hyper_util::client::legacy::connect::HttpConnector;
use serde_json::{json, Value};
use std::future::Future;
use std::net::SocketAddr;
use std::time::{Duration, Instant};
use tokio::runtime::Runtime;

/// A browser session.
pub struct Session {
    client: Client,
    runtime: Runtime,
}

impl Session {
    /// A new headless Chromium (`binary`) through the chromedriver at `driver`.
    pub fn new(driver: SocketAddr, binary: &str) -> Session {
        Session::with_args(driver, binary, &[])
    }

    /// The same, with more command-line `args` for Chromium (such as
    /// `--host-resolver-rules`, which gives a test host names of its own).
    pub fn with_args(driver: SocketAddr, binary: &str, args: &[&str]) -> Session {
        let mut all = vec![
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--window-size=1280,1100",
        ];
        all.extend_from_slice(args);
        let capabilities = json!({
            "browserName": "chrome",
            "goog:chromeOptions": { "binary": binary, "args": all },
        });
        let Value::Object(capabilities) = capabilities else {
            unreachable!("an object")
        };
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("a runtime");
        // chromedriver speaks plain HTTP on loopback: no TLS connector.
        let client = runtime
            .block_on(
                ClientBuilder::new(HttpConnector::new())
                    .capabilities(capabilities)
                    .connect(&format!("http://{driver}")),
            )
            .unwrap_or_else(|e| panic!("chromedriver made no session: {e}"));
        Session { client, runtime }
    }

    /// Runs a WebDriver command to its end; what it gave, or a panic naming `what` failed.
    fn run<T, E: std::fmt::Display>(
        &self,
        what: &str,
        command: impl Future<Output = Result<T, E>>,
    ) -> T {
        self.runtime
            .block_on(command)
            .unwrap_or_else(|e| panic!("WebDriver {what}: {e}"))
    }

    /// Opens `url`.
    pub fn open(&self, url: &str) {
        self.run(&format!("open {url}"), self.client.goto(url));
    }

    /// The element `css` selects (the first): its WebDriver id.
    pub fn find(&self, css: &str) -> String {
        let found = self.run(&format!("find {css}"), self.client.find(Locator::Css(css)));
        found.element_id().into()
    }

    /// What `css` selects, to act on.
    fn element(&self, css: &str) -> Element {
        Element::from_element_id(self.client.clone(), self.find(css).into())
    }

    /// How many elements `css` selects.
    pub fn count(&self, css: &str) -> usize {
        let found = self.client.find_all(Locator::Css(css));
        self.run(&format!("find all {css}"), found).len()
    }

    /// Sizes the browser's window, CSS pixels.
    pub fn resize(&self, width: u32, height: u32) {
        let resized = self.client.set_window_size(width, height);
        self.run(&format!("resize to {width}×{height}"), resized);
    }

    /// Goes into the page's frame number `index` (`None`: back out of the frame, to the
    /// page that holds it).
    pub fn frame(&self, index: Option<u64>) {
        match index {
            Some(index) => {
                let index = u16::try_from(index).expect("a frame's index, at most 65535");
                self.run(&format!("frame {index}"), self.client.enter_frame(index));
            }
            None => self.run("parent frame", self.client.enter_parent_frame()),
        }
    }

    /// Clicks what `css` selects, as a user would.
    pub fn click(&self, css: &str) {
        self.run(&format!("click {css}"), self.element(css).click());
    }

    /// Whether what `css` selects is shown.
    pub fn displayed(&self, css: &str) -> bool {
        let element = self.element(css);
        self.run(&format!("displayed {css}"), element.is_displayed())
    }

    /// Runs `script` in the page; its return value.
    pub fn script(&self, script: &str) -> Value {
        self.run(script, self.client.execute(script, Vec::new()))
    }

    /// The text of the element with id `id`.
    pub fn text(&self, id: &str) -> String {
        self.script(&format!(
            "return document.getElementById({id:?}).textContent"
        ))
        .as_str()
        .unwrap_or_default()
        .to_owned()
    }

    /// Waits (up to `limit`) until `check` gives something, saying what it waits for.
    pub fn wait<T>(
        &self,
        what: &str,
        limit: Duration,
        mut check: impl FnMut(&Session) -> Option<T>,
    ) -> T {
        let start = Instant::now();
        loop {
            if let Some(found) = check(self) {
                return found;
            }
            assert!(
                start.elapsed() < limit,
                "waited {limit:?} for {what}; {} shows: {}",
                self.script("return location.href"),
                self.script(
                    "return (document.getElementById('run-view') || document.body).textContent"
                )
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// A screenshot of the page, PNG.
    pub fn screenshot(&self) -> Vec<u8> {
        self.run("screenshot", self.client.screenshot())
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        // Ends the browser; a session already lost (chromedriver gone) has nothing to end.
        let _ = self.runtime.block_on(self.client.clone().close());
    }
}
