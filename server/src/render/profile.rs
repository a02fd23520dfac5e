//! Per-pass timing of a frame for the benchmark: when profiling, every pass is submitted on
//! its own and waited for, so its wall time is the GPU's (on lavapipe: the CPU's) time for it.
//! Without profiling the recorder only collects the passes into one command buffer.

use super::{Gpu, RenderError};
use std::time::Instant;

/// Wall times of a frame's passes in milliseconds, in order.
pub type PassTimes = Vec<(&'static str, f64)>;

/// Records a frame's passes into command encoders, optionally timing each.
pub struct Recorder<'a> {
    gpu: &'a Gpu,
    encoder: wgpu::CommandEncoder,
    times: Option<&'a mut PassTimes>,
    last: Instant,
}

impl<'a> Recorder<'a> {
    /// A recorder; `times` receives one entry per [`Recorder::mark`] when given.
    pub fn new(gpu: &'a Gpu, times: Option<&'a mut PassTimes>) -> Recorder<'a> {
        Recorder { gpu, encoder: Self::encoder_for(gpu), times, last: Instant::now() }
    }

    fn encoder_for(gpu: &Gpu) -> wgpu::CommandEncoder {
        gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") })
    }

    /// The encoder the next pass records into.
    pub fn encoder(&mut self) -> &mut wgpu::CommandEncoder {
        &mut self.encoder
    }

    /// Ends the pass `name`: when profiling, submits what was recorded, waits for it and notes
    /// the time since the previous mark.
    pub fn mark(&mut self, name: &'static str) -> Result<(), RenderError> {
        if self.times.is_none() {
            return Ok(());
        }
        let encoder = std::mem::replace(&mut self.encoder, Self::encoder_for(self.gpu));
        self.gpu.queue.submit([encoder.finish()]);
        self.gpu.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| RenderError::Readback(e.to_string()))?;
        let now = Instant::now();
        if let Some(times) = self.times.as_deref_mut() {
            times.push((name, (now - self.last).as_secs_f64() * 1e3));
        }
        self.last = now;
        Ok(())
    }

    /// Submits what remains; returns the recorder's timing state for marks of CPU-side work
    /// (read-back) that follow.
    pub fn submit(self) -> Timer<'a> {
        self.gpu.queue.submit([self.encoder.finish()]);
        Timer { times: self.times, last: self.last }
    }
}

/// Marks CPU-side steps after the frame's submission.
pub struct Timer<'a> {
    times: Option<&'a mut PassTimes>,
    last: Instant,
}

impl Timer<'_> {
    /// Notes the time since the previous mark as `name` (when profiling).
    pub fn mark(&mut self, name: &'static str) {
        let now = Instant::now();
        if let Some(times) = self.times.as_deref_mut() {
            times.push((name, (now - self.last).as_secs_f64() * 1e3));
        }
        self.last = now;
    }
}
