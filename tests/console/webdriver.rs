//! Enough of the W3C WebDriver protocol to drive a headless Chromium through chromedriver:
//! open a page, find and click elements, run a script, take a screenshot.

use super::http::request;
use serde_json::{json, Value};
use std::net::SocketAddr;
use std::time::{Duration, Instant};

/// The key under which WebDriver names an element.
const ELEMENT: &str = "element-6066-11e4-a52e-4f735466cecf";

/// A browser session.
pub struct Session {
    driver: SocketAddr,
    id: String,
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
        let capabilities = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": { "binary": binary, "args": all },
        }}});
        let answer = request(
            driver,
            "POST",
            "/session",
            &[],
            Some(&capabilities.to_string()),
        );
        let value = answer.json();
        let id = value["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("chromedriver made no session: {}", answer.body))
            .to_owned();
        Session { driver, id }
    }

    fn call(&self, method: &str, path: &str, body: Option<Value>) -> Value {
        let path = format!("/session/{}{path}", self.id);
        let body = body.map(|b| b.to_string());
        let answer = request(self.driver, method, &path, &[], body.as_deref());
        let value = answer.json();
        assert!(
            answer.status == 200,
            "WebDriver {method} {path}: {}",
            answer.body
        );
        value["value"].clone()
    }

    /// Opens `url`.
    pub fn open(&self, url: &str) {
        self.call("POST", "/url", Some(json!({ "url": url })));
    }

    /// The element `css` selects (the first).
    pub fn find(&self, css: &str) -> String {
        let value = self.call(
            "POST",
            "/element",
            Some(json!({"using": "css selector", "value": css})),
        );
        value[ELEMENT].as_str().expect("an element").to_owned()
    }

    /// How many elements `css` selects.
    pub fn count(&self, css: &str) -> usize {
        self.call(
            "POST",
            "/elements",
            Some(json!({"using": "css selector", "value": css})),
        )
        .as_array()
        .map_or(0, Vec::len)
    }

    /// Sizes the browser's window, CSS pixels.
    pub fn resize(&self, width: u32, height: u32) {
        self.call(
            "POST",
            "/window/rect",
            Some(json!({"width": width, "height": height})),
        );
    }

    /// Goes into the page's frame number `index` (`None`: back to the top page).
    pub fn frame(&self, index: Option<u64>) {
        self.call("POST", "/frame", Some(json!({ "id": index })));
    }

    /// Clicks what `css` selects, as a user would.
    pub fn click(&self, css: &str) {
        let element = self.find(css);
        self.call(
            "POST",
            &format!("/element/{element}/click"),
            Some(json!({})),
        );
    }

    /// Whether what `css` selects is shown.
    pub fn displayed(&self, css: &str) -> bool {
        let element = self.find(css);
        self.call("GET", &format!("/element/{element}/displayed"), None)
            .as_bool()
            .unwrap_or(false)
    }

    /// Runs `script` in the page; its return value.
    pub fn script(&self, script: &str) -> Value {
        self.call(
            "POST",
            "/execute/sync",
            Some(json!({"script": script, "args": []})),
        )
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
        let value = self.call("GET", "/screenshot", None);
        base64(value.as_str().expect("a screenshot"))
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        let path = format!("/session/{}", self.id);
        request(self.driver, "DELETE", &path, &[], None);
    }
}

/// Decodes standard base64 (what WebDriver sends screenshots in).
fn base64(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let digits: Vec<u8> = text
        .bytes()
        .filter(|c| !c.is_ascii_whitespace() && *c != b'=')
        .map(value)
        .collect();
    digits
        .chunks(4)
        .flat_map(|chunk| {
            let n = chunk
                .iter()
                .enumerate()
                .fold(0u32, |n, (i, &d)| n | u32::from(d) << (18 - 6 * i));
            let bytes = [(n >> 16) as u8, (n >> 8) as u8, n as u8];
            bytes.into_iter().take(chunk.len().saturating_sub(1))
        })
        .collect()
}

#[test]
fn base64_decodes_as_the_standard_says() {
    // RFC 4648's test vectors.
    for (text, plain) in [
        ("", ""),
        ("Zg==", "f"),
        ("Zm8=", "fo"),
        ("Zm9v", "foo"),
        ("Zm9vYg==", "foob"),
        ("Zm9vYmE=", "fooba"),
        ("Zm9vYmFy", "foobar"),
    ] {
        assert_eq!(base64(text), plain.as_bytes());
    }
}
