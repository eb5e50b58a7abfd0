"""Choosing the OpenCL device by what builds (cl/devices.py), independent of this machine's CPU.

Devices that cannot build are injected: a device listed beside the real ones whose probe build
fails with the compiler's words of the bundled PoCL on a too-new CPU. The order, the skip and
its reason, the error when nothing builds, and the verdict cache are checked against them.
The rules that need no OpenCL at all (naming drivers, spotting the bundled PoCL, the order)
run on plain data."""

from __future__ import annotations

import pytest

from btf_addon.cl import context as cl_context
from btf_addon.cl import devices, programs
from btf_addon.cl.devices import DeviceInfo, Verdict

TOO_NEW = "error: unknown target CPU 'generic'"  # the bundled PoCL 3.0 on AMD Zen 5


def info(name, kind="CPU", units=4, driver="PoCL 3.1+debian", bundled=False) -> DeviceInfo:
    return DeviceInfo(
        platform="Portable Computing Language", name=name, type=kind, compute_units=units,
        global_memory_mb=1024, opencl_version="OpenCL 3.0", driver=driver,
        driver_version=driver.split()[-1], bundled=bundled,
    )  # fmt: skip


# -- rules on plain data ----------------------------------------------------------------------


@pytest.mark.parametrize(
    "version, name, words",
    [
        (
            "OpenCL 3.0 PoCL 3.1+debian  Linux, None+Asserts, RELOC, LLVM 15.0.6",
            "x",
            "PoCL 3.1+debian",
        ),
        ("OpenCL 3.0 PoCL 3.0-rc2  Linux, Release, RELOC, LLVM 14.0.6", "x", "PoCL 3.0-rc2"),
        ("OpenCL 3.0 CUDA 12.4.131", "NVIDIA CUDA", "CUDA 12.4.131"),
        ("OpenCL 2.1 AMD-APP (3614.0)", "AMD", "AMD-APP (3614.0)"),
        ("OpenCL 1.2", "Apple", "Apple"),
    ],
)
def test_driver_words_tell_drivers_apart(version, name, words):
    assert devices.driver_words(version, name) == words


def test_the_bundled_pocl_is_told_by_its_version():
    assert devices._is_bundled("PoCL 3.0-rc2", "3.0")
    assert devices._is_bundled("PoCL 3.0", "3.0")
    assert not devices._is_bundled("PoCL 3.1+debian", "3.0")
    assert not devices._is_bundled("PoCL 3.0-rc2", None)  # not installed: nothing is bundled
    assert not devices._is_bundled("CUDA 3.0", "3.0")


def test_labels_name_the_driver():
    system = info("pthread-AMD EPYC")
    bundled = info("pthread-AMD EPYC", driver="PoCL 3.0-rc2", bundled=True)
    assert system.label == "pthread-AMD EPYC (PoCL 3.1+debian)"
    assert bundled.label == "pthread-AMD EPYC (PoCL 3.0-rc2, bundled)"
    assert system.probe_key != bundled.probe_key


def test_order_chosen_then_gpus_then_system_cpus_then_bundled():
    listed = [
        info("bundled cpu", driver="PoCL 3.0-rc2", bundled=True),  # 0
        info("system cpu"),  # 1
        info("small gpu", kind="GPU", units=8, driver="CUDA 12.4"),  # 2
        info("big gpu", kind="GPU", units=64, driver="CUDA 12.4"),  # 3
        info("other cpu", driver="Intel 2024"),  # 4
    ]
    assert devices.candidate_order(listed) == [3, 2, 1, 4, 0]
    assert devices.candidate_order(listed, chosen=0) == [0, 3, 2, 1, 4]
    assert devices.best_device_index(listed) == 3


# -- the choice on this machine's drivers, with injected failures ----------------------------


@pytest.fixture
def injected(monkeypatch, tmp_path):
    """``add(info, verdict)`` lists a fake device first (before the real ones) whose probe
    gives ``verdict``; ``fail_real(reason)`` makes every real device's probe fail too. Verdicts
    are cached in a folder of this test's own."""
    try:
        real = devices.discover()
    except devices.OpenCLUnavailableError as exc:
        pytest.skip(f"no OpenCL platform ({exc}); setup installs PoCL")
    monkeypatch.setattr(programs, "_cache_dir_setting", tmp_path / "cache")
    monkeypatch.setattr(devices, "_verdicts", {})
    fakes: list[tuple[DeviceInfo, object]] = []
    verdicts: dict[int, Verdict] = {}
    real_build = devices.build_probe
    built: list[object] = []

    def build(device):
        built.append(device)
        if id(device) in verdicts:
            return verdicts[id(device)]
        return real_build(device)

    monkeypatch.setattr(devices, "discover", lambda: [*fakes, *real])
    monkeypatch.setattr(devices, "build_probe", build)

    class Injector:
        real_devices = real
        builds = built

        def add(self, fake: DeviceInfo, verdict: Verdict):
            device = object()
            fakes.append((fake, device))
            verdicts[id(device)] = verdict
            return device

        def fail_real(self, reason: str):
            for _, device in real:
                verdicts[id(device)] = Verdict(False, reason)

    return Injector()


def test_a_device_that_cannot_build_is_skipped_with_its_reason(injected):
    fake = info("Injected GPU", kind="GPU", units=999, driver="FakeCL 1.0")
    injected.add(fake, Verdict(False, TOO_NEW))
    ctx = cl_context.create_context()  # the fake GPU is tried first (GPUs first)
    assert ctx.info != fake and ctx.skipped == ((fake, TOO_NEW),)
    assert ctx.device_name == ctx.info.label
    # The context works: it builds a real program.
    programs.build_program(ctx.context, ctx.device, "btf_eval.cl", {})


def test_the_users_choice_is_tried_first_and_skipped_when_it_cannot_build(injected):
    fake = info("Injected CPU", driver="FakeCL 1.0")
    injected.add(fake, Verdict(False, TOO_NEW))
    ctx = cl_context.create_context(0)  # index 0: the injected device, as the user chose
    assert ctx.skipped[0] == (fake, TOO_NEW) and ctx.info != fake


def test_nothing_builds_names_every_device_and_what_to_install(injected):
    injected.add(info("Injected GPU", kind="GPU", driver="FakeCL 1.0"), Verdict(False, TOO_NEW))
    injected.fail_real("error: injected failure")
    with pytest.raises(devices.OpenCLUnavailableError) as failure:
        cl_context.create_context()
    exc = failure.value
    assert "no OpenCL device can build programs" in exc.reason
    assert f"Injected GPU (FakeCL 1.0): {TOO_NEW}" in exc.reason
    for real, _ in injected.real_devices:
        assert f"{real.label}: error: injected failure" in exc.reason
    assert exc.advice == cl_context.install_advice() and exc.advice in str(exc)


def test_the_verdict_is_cached_on_disk_per_driver(injected, monkeypatch):
    fake = info("Injected GPU", kind="GPU", driver="FakeCL 1.0")
    fake_device = injected.add(fake, Verdict(False, TOO_NEW))
    cl_context.create_context()
    probed = len(injected.builds)
    assert probed >= 2  # the fake and the real device chosen
    cl_context.create_context()
    assert len(injected.builds) == probed  # the same process: from memory
    monkeypatch.setattr(devices, "_verdicts", {})  # a new process: from the disk cache
    ctx = cl_context.create_context()
    assert len(injected.builds) == probed and ctx.skipped == ((fake, TOO_NEW),)
    # A new driver version is probed again.
    newer = info("Injected GPU", kind="GPU", driver="FakeCL 1.1")
    newer_device = injected.add(newer, Verdict(True))
    report = {row["label"]: row for row in devices.device_report()}
    assert injected.builds.count(newer_device) == 1 and injected.builds.count(fake_device) == 1
    assert report[newer.label]["builds"] and not report[fake.label]["builds"]
    # Another machine sharing the cache folder (a farm node, a shared home): probed again,
    # since one device name ("pthread-AMD EPYC") covers CPUs its compiler may not target.
    monkeypatch.setattr(devices, "_verdicts", {})
    monkeypatch.setattr(devices, "_machine_identity", lambda: "another-node:0123456789ab")
    devices.device_report()
    assert injected.builds.count(fake_device) == 2


def test_report_marks_the_device_f12_uses(injected):
    fake = info("Injected GPU", kind="GPU", driver="FakeCL 1.0")
    injected.add(fake, Verdict(False, TOO_NEW))
    report = devices.device_report()
    used = [row for row in report if row["used"]]
    assert len(used) == 1 and used[0]["label"] == cl_context.create_context().info.label
    assert report[0]["label"] == fake.label and report[0]["reason"] == TOO_NEW


def test_every_real_device_is_probed_for_real():
    """No injection: each device of this machine gets a verdict from a real build; a device
    that fails says why in the compiler's words."""
    try:
        report = devices.device_report()
    except devices.OpenCLUnavailableError as exc:
        pytest.skip(f"no OpenCL platform ({exc})")
    for row in report:
        assert row["builds"] or row["reason"], row
    assert sum(row["used"] for row in report) == (1 if any(r["builds"] for r in report) else 0)
