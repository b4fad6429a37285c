from setuptools import find_packages, setup

package_name = "team_clock"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{package_name}"]),
        (f"share/{package_name}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="efficient_comm dev",
    maintainer_email="dev@example.com",
    description="Clock offsets between robots and time-aligned merging of their logs.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "team_clock = team_clock.cli:main",
            "clock_sync = team_clock.sync:main",
        ],
        "efficient_comm.components": [
            "clock_sync = team_clock.sync:ClockSync",
        ],
    },
)
