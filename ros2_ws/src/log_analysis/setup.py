from setuptools import find_packages, setup

package_name = "log_analysis"

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
    description="Offline analysis of team logs: sources on one time base, event generators "
                "and their sidecar MCAP.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "events = log_analysis.cli:events_main",
            "sync-video = log_analysis.cli:sync_video_main",
            "augment = log_analysis.cli:augment_main",
            "compare = log_analysis.cli:compare_main",
        ],
        "log_analysis.event_generators": [
            "falls = log_analysis.generators:Falls",
            "ball_lost = log_analysis.generators:BallLost",
            "role_oscillation = log_analysis.generators:RoleOscillation",
            "long_callbacks = log_analysis.generators:LongCallbacks",
            "ball_disagreement = log_analysis.generators:BallDisagreement",
            "localization_jump = log_analysis.generators:LocalizationJump",
            "team_link_silent = log_analysis.generators:TeamLinkSilent",
            "goals = log_analysis.generators:Goals",
        ],
    },
)
