//! Reading GPU buffers back to the host, and timing passes with timestamp queries.
//!
//! Reads are `async` because the browser cannot block: there a buffer maps only after control returns to the
//! event loop, so the whole voxelization is a future that the web page spawns. Natively the same futures finish
//! on their first poll, because [`map_and_copy`] waits for the device before awaiting the map.

use super::GpuError;
use std::time::Duration;

/// How long a blocking wait for the GPU may take before it is given up on with [`GpuError::Timeout`]: 120 s, or
/// `MESHVOX_GPU_TIMEOUT` seconds. One wait covers one slab's passes and readback, which take milliseconds to
/// seconds on real adapters; a device that does not answer in minutes has hung.
pub fn watchdog() -> Duration {
    static TIMEOUT: std::sync::OnceLock<Duration> = std::sync::OnceLock::new();
    *TIMEOUT.get_or_init(|| {
        std::env::var("MESHVOX_GPU_TIMEOUT")
            .ok()
            .and_then(|s| s.trim().parse::<f64>().ok())
            .and_then(|s| Duration::try_from_secs_f64(s).ok())
            .unwrap_or(Duration::from_secs(120))
    })
}

/// Blocks until the device has finished the work submitted so far, at most [`watchdog`] long. (A no-op in the
/// browser, where work finishes while futures yield to the event loop.) A limit of zero gives up on every wait
/// without asking the device: whether a zero-length wait succeeds would otherwise depend on whether the GPU
/// happened to finish first, and `MESHVOX_GPU_TIMEOUT=0` is how the fallback path is tried on purpose.
pub(crate) fn wait(device: &wgpu::Device) -> Result<(), GpuError> {
    let timeout = watchdog();
    let _wait = crate::trace::device_wait();
    if timeout.is_zero() {
        return Err(GpuError::Timeout(0.0));
    }
    match device.poll(wgpu::PollType::Wait { submission_index: None, timeout: Some(timeout) }) {
        Ok(_) => Ok(()),
        Err(wgpu::PollError::Timeout) => Err(GpuError::Timeout(timeout.as_secs_f64())),
        Err(e) => Err(GpuError::Device(e.to_string())),
    }
}

/// A MAP_READ buffer of `size` bytes (four at least) for one readback.
fn staging_buffer(device: &wgpu::Device, size: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("meshvox readback"),
        size: size.max(4),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Copies `size` bytes of `buffer` (from `offset`, a multiple of four) into host memory once the GPU is done, as
/// values of `T` (bytes, or the words or floats they hold), copied once: straight out of the mapped range.
pub(crate) async fn read_buffer<T: bytemuck::Pod>(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    buffer: &wgpu::Buffer,
    offset: u64,
    size: u64,
) -> Result<Vec<T>, GpuError> {
    let mut values = Vec::new();
    read_buffer_with(device, queue, buffer, (offset, size), |mapped| values = bytemuck::pod_collect_to_vec(mapped))
        .await?;
    Ok(values)
}

/// Hands `size` bytes of `buffer` (from `offset`, a multiple of four) to `take` straight out of the mapped range
/// once the GPU is done: for a reader that makes what it keeps of them as it reads (no copy first).
pub(crate) async fn read_buffer_with(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    buffer: &wgpu::Buffer,
    (offset, size): (u64, u64),
    take: impl FnOnce(&[u8]),
) -> Result<(), GpuError> {
    let staging = staging_buffer(device, size);
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, offset, &staging, 0, size);
    super::util::submit(queue, encoder.finish());
    map_range(device, &staging, size, take).await
}

/// Copies several `(buffer, offset, size)` ranges (sizes multiples of four) into one staging buffer and maps it
/// once: in the browser every map is a round trip to the GPU process, so reads that can share one do.
pub(crate) async fn read_buffers(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    ranges: &[(&wgpu::Buffer, u64, u64)],
) -> Result<Vec<Vec<u8>>, GpuError> {
    let total: u64 = ranges.iter().map(|r| r.2).sum();
    let staging = staging_buffer(device, total);
    let mut encoder = device.create_command_encoder(&Default::default());
    let mut at = 0;
    for &(buffer, offset, size) in ranges {
        encoder.copy_buffer_to_buffer(buffer, offset, &staging, at, size);
        at += size;
    }
    super::util::submit(queue, encoder.finish());
    let bytes = map_and_copy(device, &staging).await?;
    if ranges.len() == 1 {
        // One range (most reads, grids included): no second copy.
        return Ok(vec![bytes]);
    }
    let mut at = 0;
    Ok(ranges
        .iter()
        .map(|r| {
            let part = bytes[at..at + r.2 as usize].to_vec();
            at += r.2 as usize;
            part
        })
        .collect())
}

/// The size of each of the two staging buffers a grid is streamed through ([`stream_buffer`]), or the device's
/// largest buffer where that is smaller.
pub(crate) const STREAM_CHUNK: u64 = 4 << 20;

/// Two MAP_READ buffers of [`STREAM_CHUNK`] bytes (at most), kept by a voxelizer between runs ([`StreamPool`]).
pub(crate) struct Stream([wgpu::Buffer; 2]);

/// The idle [`Stream`]s of a voxelizer: a run takes one (or makes one) and gives it back, so runs at the same
/// time never share a buffer, and a voxelizer that runs again reuses pages the driver has already mapped.
#[derive(Default)]
pub(crate) struct StreamPool(std::sync::Mutex<Vec<Stream>>);

impl StreamPool {
    fn take(&self, device: &wgpu::Device) -> Stream {
        let idle = self.0.lock().map(|mut idle| idle.pop()).unwrap_or(None);
        idle.unwrap_or_else(|| {
            Stream(std::array::from_fn(|_| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("meshvox grid stream"),
                    size: STREAM_CHUNK.min(device.limits().max_buffer_size) & !7,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            }))
        })
    }

    fn give_back(&self, stream: Stream) {
        if let Ok(mut idle) = self.0.lock() {
            idle.push(stream);
        }
    }
}

/// Reads the first `size` bytes of `source` (a multiple of four) through a pair of reused staging buffers, a
/// chunk ([`STREAM_CHUNK`]) at a time, handing each chunk straight from the mapped memory to
/// `sink(offset, bytes)`: while the host takes one chunk, the other is being copied.
///
/// Why not one staging buffer the size of the grid, mapped and copied into a `Vec`, as [`read_buffers`] does:
/// that touches three fresh regions of the grid's size (staging, `Vec`, host grid), and first touches are what
/// the readback cost (~2.9 ns per grid byte on the H100 and on lavapipe alike, where the passes took 0.3 ms).
///
/// The bytes read are `source[start..start + size]`, and each chunk handed over is a whole number of `unit`s (a
/// multiple of four: a grid word, a sparse run's slot), so that the sink never sees one cut in two.
#[allow(clippy::too_many_arguments)]
pub(crate) async fn stream_buffer(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    pool: &StreamPool,
    source: &wgpu::Buffer,
    start: u64,
    size: u64,
    unit: u64,
    mut sink: impl FnMut(u64, &[u8]),
) -> Result<(), GpuError> {
    let stream = pool.take(device);
    let chunk = (stream.0[0].size() / unit * unit).max(unit);
    let chunks = size.div_ceil(chunk);
    let span = |i: u64| (i * chunk, chunk.min(size - i * chunk));
    let copy = |i: u64| {
        let (at, len) = span(i);
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(source, start + at, &stream.0[(i % 2) as usize], 0, len);
        super::util::submit(queue, encoder.finish());
    };
    let mut result = Ok(());
    for i in 0..chunks.min(2) {
        copy(i);
    }
    for i in 0..chunks {
        let (at, len) = span(i);
        let staging = &stream.0[(i % 2) as usize];
        if let Err(e) = map_range(device, staging, len, |bytes| sink(at, bytes)).await {
            result = Err(e);
            break;
        }
        if i + 2 < chunks {
            copy(i + 2);
        }
    }
    // A buffer left mapped by a failed map cannot be reused; the pool only takes back a clean pair.
    if result.is_ok() {
        pool.give_back(stream);
    }
    result
}

/// Maps the first `len` bytes of a MAP_READ buffer, hands them to `take`, and unmaps it.
async fn map_range(
    device: &wgpu::Device,
    staging: &wgpu::Buffer,
    len: u64,
    take: impl FnOnce(&[u8]),
) -> Result<(), GpuError> {
    let slice = staging.slice(..len);
    let (tx, rx) = futures_channel::oneshot::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    // Natively this blocks until the copy is done and the callback has run; in the browser it returns at once
    // and the map completes while the await below yields to the event loop.
    wait(device)?;
    rx.await
        .map_err(|_| GpuError::DeviceLost("the device was lost before a readback finished".into()))?
        .map_err(|e| GpuError::Device(format!("cannot map a readback buffer: {e}")))?;
    let _span = crate::trace::span("map and take");
    take(&slice.get_mapped_range().map_err(|e| GpuError::Device(e.to_string()))?);
    staging.unmap();
    Ok(())
}

/// The first little-endian `u32` of a readback (a counter), or `None` if fewer than four bytes came back.
pub(crate) fn first_word(bytes: &[u8]) -> Option<u32> {
    bytes.get(..4).and_then(|b| b.try_into().ok()).map(u32::from_le_bytes)
}

/// Maps a MAP_READ buffer and returns its contents.
pub(crate) async fn map_and_copy(device: &wgpu::Device, staging: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
    let mut bytes = Vec::new();
    map_range(device, staging, staging.size(), |mapped| bytes = mapped.to_vec()).await?;
    Ok(bytes)
}

/// A query set with a begin/end pair per compute pass, resolved into a buffer that is read with the results.
pub(crate) struct PassTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    capacity: u32,
    used: u32,
}

impl PassTimer {
    pub(crate) fn new(device: &wgpu::Device, passes: u32) -> PassTimer {
        let capacity = passes * 2;
        PassTimer {
            set: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("meshvox timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: capacity,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("meshvox timestamps resolve"),
                size: capacity as u64 * 8,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            capacity,
            used: 0,
        }
    }

    /// Timestamp writes for the next pass, or `None` when the set is full.
    pub(crate) fn next_pass(&mut self) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        if self.used + 2 > self.capacity {
            return None;
        }
        let begin = self.used;
        self.used += 2;
        Some(wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(begin),
            end_of_pass_write_index: Some(begin + 1),
        })
    }

    /// Resolves the written queries into the resolve buffer with `encoder`; returns how many bytes of
    /// [`PassTimer::resolved`] to read back (zero when no pass was timed).
    pub(crate) fn resolve(&mut self, encoder: &mut wgpu::CommandEncoder) -> u64 {
        if self.used > 0 {
            encoder.resolve_query_set(&self.set, 0..self.used, &self.resolve, 0);
        }
        self.used as u64 * 8
    }

    pub(crate) fn resolved(&self) -> &wgpu::Buffer {
        &self.resolve
    }

    /// Sums the pass times in read-back resolved queries, in milliseconds; the timer is then empty again.
    pub(crate) fn finish(&mut self, queue: &wgpu::Queue, bytes: &[u8]) -> f64 {
        let ticks: Vec<u64> =
            bytes.chunks_exact(8).map(|b| u64::from_le_bytes(b.try_into().unwrap_or_default())).collect();
        let period = queue.get_timestamp_period() as f64;
        let ns: f64 = ticks.chunks_exact(2).map(|p| p[1].saturating_sub(p[0]) as f64 * period).sum();
        self.used = 0;
        ns / 1e6
    }
}
