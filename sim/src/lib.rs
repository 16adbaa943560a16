//! whirl-sim: a simulated whirling-lathe controller.
