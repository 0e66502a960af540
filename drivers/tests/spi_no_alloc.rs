//! An SPI transaction of the tension converters performs no heap allocation (counted by a global
//! allocator wrapper, per thread), where linux-embedded-hal's `SpidevDevice` allocates on every
//! one. The device here is `/dev/null`: the kernel refuses the transfer, after everything the
//! driver does on its own side.
#![cfg(target_os = "linux")]

use embedded_hal::spi::{Operation, SpiDevice};
use linux_embedded_hal::spidev::Spidev;
use linux_embedded_hal::SpidevDevice;
use videt_drivers::adc::linux::{RtSpiError, RtSpidev};

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

fn null_spidev() -> Spidev {
    Spidev::new(std::fs::File::open("/dev/null").unwrap())
}

/// The ADS1220's conversion read: a command byte out, three data bytes in.
fn read_conversion<S: SpiDevice>(spi: &mut S) -> Result<(), S::Error> {
    let mut data = [0u8; 3];
    spi.transaction(&mut [Operation::Write(&[0x10]), Operation::Read(&mut data)])
}

#[test]
fn a_conversion_read_does_not_allocate() {
    let mut ours = RtSpidev::from_spidev(null_spidev());
    let (result, counts) = videt_testkit::count_allocations(|| read_conversion(&mut ours));
    assert!(matches!(result, Err(RtSpiError::Io(_))), "{result:?}");
    assert_eq!(counts.allocations, 0);

    let mut theirs = SpidevDevice(null_spidev());
    let (result, counts) = videt_testkit::count_allocations(|| read_conversion(&mut theirs));
    assert!(result.is_err());
    assert!(
        counts.allocations >= 1,
        "linux-embedded-hal's SpidevDevice no longer allocates per transaction: {counts:?}"
    );
}

#[test]
fn too_many_operations_are_refused_before_the_bus() {
    let mut spi = RtSpidev::from_spidev(null_spidev());
    let mut ops = [
        Operation::Write(&[1]),
        Operation::Write(&[2]),
        Operation::Write(&[3]),
        Operation::Write(&[4]),
        Operation::Write(&[5]),
    ];
    assert_eq!(
        spi.transaction(&mut ops),
        Err(RtSpiError::TooManyOperations(5))
    );
    let (mut a, b) = ([0u8; 2], [0u8; 3]);
    assert_eq!(
        spi.transaction(&mut [Operation::Transfer(&mut a, &b)]),
        Err(RtSpiError::LengthMismatch)
    );
}
